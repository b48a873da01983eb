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
    frame.name = file.filename().string();
    ++next_;
    try {
      frame.image = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& e) {
      frame.unreadable = std::string("OpenCV cannot read it (") + e.what() + ")";
      return frame;
    }
    if (frame.image.empty()) {
      frame.unreadable = "not an image OpenCV can read (a corrupt or truncated file?)";
      return frame;
    }
    if (frame.image.depth() != CV_8U ||
        (frame.image.channels() != 1 && frame.image.channels() != 3 &&
         frame.image.channels() != 4)) {
      frame.unreadable = "not an 8-bit grey, BGR or BGRA image";
      frame.image = cv::Mat();
      return frame;
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
    if (pending_) {
      Frame frame = std::move(*pending_);
      pending_.reset();
      return frame;
    }
    Frame frame;
    if (Read(frame)) return frame;
    if (live_) return std::nullopt;  // a device or stream that stopped
    // A file's frame that does not decode, or its end: a frame that decodes after it tells
    // them apart (it is kept for the next call).
    Frame bad;
    bad.index = index_++;
    bad.stamp = TimeFromSeconds(static_cast<double>(bad.index) / camera_.rate_hz);
    bad.name = "frame " + std::to_string(bad.index);
    bad.unreadable = "does not decode";
    for (int k = 0; k < kMaxFailuresInARow; ++k) {
      Frame next;
      if (Read(next)) {
        pending_ = std::move(next);
        return bad;
      }
    }
    return std::nullopt;
  }
  [[nodiscard]] std::string description() const override { return source_; }

 private:
  std::string source_;
  CameraConfig camera_;
  // Reads the next frame into `frame` (its index, stamp and name too); false when none decodes.
  bool Read(Frame& frame) {
    if (!capture_.read(frame.image) || frame.image.empty()) return false;
    frame.index = index_++;
    frame.name = "frame " + std::to_string(frame.index);
    if (live_) {
      frame.stamp = SystemNow() - FromSeconds(camera_.latency_s);
    } else {
      const double ms = capture_.get(cv::CAP_PROP_POS_MSEC);
      frame.stamp = ms > 0 || frame.index == 0
                        ? TimeFromSeconds(ms / 1e3)
                        : TimeFromSeconds(static_cast<double>(frame.index) / camera_.rate_hz);
    }
    return true;
  }

  static constexpr int kMaxFailuresInARow = 30;
  cv::VideoCapture capture_;
  bool live_ = false;
  long long index_ = 0;
  std::optional<Frame> pending_;  // a frame read past an unreadable one
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
