#include "examples/cloning/dataset.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace autodrive::examples::cloning {

namespace {
std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream in(line);
  std::string cell;
  while (std::getline(in, cell, ',')) out.push_back(cell);
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}
}  // namespace

std::vector<LabelledFrame> ReadDrivingDataset(const std::filesystem::path& folder) {
  const std::filesystem::path csv = folder / "labels.csv";
  std::ifstream in(csv);
  if (!in) {
    throw InputError(csv.string() + ": cannot read it (a data set folder of autodrive-sim " +
                     "record has frames and labels.csv)");
  }
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = SplitCsv(line);
  std::map<std::string, std::size_t> column;
  for (std::size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  for (const char* need : {"frame", "throttle", "steering"}) {
    if (column.count(need) == 0) {
      throw InputError(csv.string() + ":1: no column \"" + need + "\" in the header");
    }
  }
  std::vector<LabelledFrame> out;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::vector<std::string> cells = SplitCsv(line);
    const auto where = [&] { return csv.string() + ":" + std::to_string(line_no) + ": "; };
    if (cells.size() != header.size()) {
      throw InputError(where() + std::to_string(cells.size()) + " columns, the header has " +
                       std::to_string(header.size()));
    }
    const auto number = [&](const char* name) {
      const std::string& text = cells[column.at(name)];
      std::size_t used = 0;
      double v = 0;
      try {
        v = std::stod(text, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != text.size() || !std::isfinite(v)) {
        throw InputError(where() + name + " \"" + text + "\" is not a number");
      }
      return v;
    };
    const double frame = number("frame");
    if (frame < 0 || frame != std::floor(frame)) {
      throw InputError(where() + "frame " + cells[column.at("frame")] + " is not a frame number");
    }
    LabelledFrame f;
    const double throttle = number("throttle"), steering = number("steering");
    if (std::abs(throttle) > 1.0 || std::abs(steering) > 1.0) {
      throw InputError(where() + "throttle and steering are normalised, in [-1, 1]");
    }
    f.throttle = static_cast<float>(throttle);
    f.steering = static_cast<float>(steering);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06lld", static_cast<long long>(frame));
    f.image = folder / (std::string(name) + ".png");
    if (!std::filesystem::exists(f.image)) f.image.replace_extension(".jpg");
    if (!std::filesystem::exists(f.image)) {
      throw InputError(where() + "no frame " + name + ".png (or .jpg) in " + folder.string());
    }
    out.push_back(std::move(f));
  }
  if (out.empty()) throw InputError(csv.string() + ": no labelled frame");
  return out;
}

std::vector<LabelledFrame> Balance(const std::vector<LabelledFrame>& frames, int bins,
                                   double factor, std::uint64_t seed) {
  const auto bin = [&](float s) {
    return std::clamp(static_cast<int>((s + 1.0f) / 2.0f * static_cast<float>(bins)), 0, bins - 1);
  };
  std::vector<std::vector<std::size_t>> members(static_cast<std::size_t>(bins));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    members[static_cast<std::size_t>(bin(frames[i].steering))].push_back(i);
  }
  const auto used =
      std::count_if(members.begin(), members.end(), [](const auto& m) { return !m.empty(); });
  if (used == 0) return {};
  const auto cap = static_cast<std::size_t>(
      std::ceil(factor * static_cast<double>(frames.size()) / static_cast<double>(used)));
  std::mt19937_64 rng(seed);
  std::vector<bool> keep(frames.size(), false);
  for (auto& m : members) {
    std::shuffle(m.begin(), m.end(), rng);
    for (std::size_t k = 0; k < std::min(cap, m.size()); ++k) keep[m[k]] = true;
  }
  std::vector<LabelledFrame> out;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (keep[i]) out.push_back(frames[i]);
  }
  return out;
}

cv::Mat Augment(const cv::Mat& rgb, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> brightness(0.6, 1.4), channel(0.9, 1.1);
  const double b = brightness(rng);
  const cv::Scalar gain(b * channel(rng), b * channel(rng), b * channel(rng));
  cv::Mat out;
  rgb.convertTo(out, CV_32FC3);
  cv::multiply(out, gain, out);
  cv::Mat noise(out.size(), CV_32FC3);
  cv::RNG draw(rng());
  draw.fill(noise, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(3));
  out += noise;
  cv::Mat bytes;
  out.convertTo(bytes, CV_8UC3);  // saturating
  return bytes;
}

cv::Mat ReadRgb(const std::filesystem::path& path) {
  const cv::Mat bgr = cv::imread(path.string(), cv::IMREAD_COLOR);
  if (bgr.empty()) throw InputError(path.string() + ": cannot read the frame");
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace autodrive::examples::cloning
