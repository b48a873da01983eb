#include "eye/sources.h"

#include <algorithm>
#include <filesystem>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "common/error.h"

namespace autodrive::eye {

namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

class ImageFolder final : public FrameSource {
 public:
  ImageFolder(const std::filesystem::path& folder, double rate_hz)
      : folder_(folder), rate_hz_(rate_hz) {
    std::error_code ec;
    if (!std::filesystem::is_directory(folder, ec)) {
      throw InputError("images:" + folder.string() + ": not a folder");
    }
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
      if (!entry.is_regular_file()) continue;
      const std::string ext = Lower(entry.path().extension().string());
      if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tif" ||
          ext == ".tiff" || ext == ".pgm" || ext == ".ppm") {
        files_.push_back(entry.path());
      }
    }
    std::sort(files_.begin(), files_.end());
    if (files_.empty()) throw InputError("images:" + folder.string() + ": no image files in it");
  }
  std::optional<Frame> Next() override {
    if (next_ >= files_.size()) return std::nullopt;
    const std::filesystem::path& file = files_[next_];
    Frame frame;
    frame.index = static_cast<long long>(next_);
    frame.stamp = TimeFromSeconds(static_cast<double>(next_) / rate_hz_);
    frame.image = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    frame.name = file.filename().string();
    ++next_;
    if (frame.image.empty()) throw InputError(file.string() + ": not an image OpenCV can read");
    if (frame.image.depth() != CV_8U) {
      throw InputError(file.string() + ": not an 8-bit image");
    }
    if (frame.image.channels() == 4) {
      cv::Mat bgr;
      cv::cvtColor(frame.image, bgr, cv::COLOR_BGRA2BGR);
      frame.image = bgr;
    }
    return frame;
  }
  [[nodiscard]] std::string description() const override {
    return "images:" + folder_.string() + " (" + std::to_string(files_.size()) + " files)";
  }

 private:
  std::filesystem::path folder_;
  double rate_hz_;
  std::vector<std::filesystem::path> files_;
  std::size_t next_ = 0;
};

class Capture final : public FrameSource {
 public:
  Capture(const std::string& source, const CameraConfig& camera)
      : source_(source), camera_(camera) {
    const std::string rest = source.substr(source.find(':') + 1);
    if (source.rfind("device:", 0) == 0) {
      live_ = true;
      const bool number = !rest.empty() && std::all_of(rest.begin(), rest.end(), ::isdigit);
      if (number) {
        capture_.open(std::stoi(rest), cv::CAP_V4L2);
      } else {
        capture_.open(rest, cv::CAP_V4L2);
      }
    } else if (source.rfind("url:", 0) == 0) {
      live_ = true;
      capture_.open(rest, cv::CAP_FFMPEG);
    } else {
      capture_.open(rest);
    }
    if (!capture_.isOpened()) {
      throw InputError(source +
                       ": OpenCV cannot open it (no such device, file or stream, or no "
                       "backend for it)");
    }
  }
  std::optional<Frame> Next() override {
    Frame frame;
    if (!capture_.read(frame.image) || frame.image.empty()) return std::nullopt;
    frame.index = index_++;
    if (live_) {
      frame.stamp = SystemNow() - FromSeconds(camera_.latency_s);
    } else {
      const double ms = capture_.get(cv::CAP_PROP_POS_MSEC);
      frame.stamp = ms > 0 || frame.index == 0
                        ? TimeFromSeconds(ms / 1e3)
                        : TimeFromSeconds(static_cast<double>(frame.index) / camera_.rate_hz);
    }
    return frame;
  }
  [[nodiscard]] std::string description() const override { return source_; }

 private:
  std::string source_;
  CameraConfig camera_;
  cv::VideoCapture capture_;
  bool live_ = false;
  long long index_ = 0;
};

}  // namespace

std::unique_ptr<FrameSource> OpenSource(const CameraConfig& camera) {
  const std::string& s = camera.source;
  if (s.rfind("images:", 0) == 0) {
    return std::make_unique<ImageFolder>(s.substr(7), camera.rate_hz);
  }
  if (s.rfind("video:", 0) == 0 || s.rfind("device:", 0) == 0 || s.rfind("url:", 0) == 0) {
    return std::make_unique<Capture>(s, camera);
  }
  throw InputError("camera " + camera.name + ": source " + s +
                   " is read by the online service (autodrive-eye run), not from files");
}

}  // namespace autodrive::eye
