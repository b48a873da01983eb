#pragma once
/// @file
/// Where a camera's frames come from: a folder of image files, a video file, a V4L2 device or
/// a stream (OpenCV's `VideoCapture`). The simulator's image topic is read by the online
/// service (eye/service.h).

#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "common/time.h"
#include "eye/eye_config.h"

namespace autodrive::eye {

/// One frame.
struct Frame {
  long long index = 0;  ///< 0, 1, 2, ... in the order the source gave them
  Time stamp{};         ///< the middle of its exposure, as well as the source knows it
  cv::Mat image;        ///< BGR or grey, 8-bit; empty when `unreadable`
  std::string name;     ///< the file's name for files, "frame N" for a video's frames
  /// Empty, or why the frame could not be read (a corrupt or truncated file, an image that is
  /// not 8-bit, a frame of a video that does not decode): it has no image, and the source goes
  /// on with the next frame.
  std::string unreadable;
};

/// A camera's frames, one after the other. Not thread-safe: one reader.
class FrameSource {
 public:
  FrameSource() = default;
  FrameSource(const FrameSource&) = delete;
  FrameSource& operator=(const FrameSource&) = delete;
  virtual ~FrameSource() = default;
  /// The next frame; `std::nullopt` at the end of files, or when a live source has stopped.
  /// A frame that cannot be read comes with `unreadable` set and no image (the caller counts
  /// and skips it, or stops); its index and stamp are where it would have been.
  virtual std::optional<Frame> Next() = 0;
  /// What it reads, for messages: "images:/path (300 files)".
  [[nodiscard]] virtual std::string description() const = 0;
};

/// Opens the camera's source: `images:DIR` (every .png, .jpg, .jpeg, .bmp, .tif, .tiff, .pgm,
/// .ppm in name order, stamped index / rate_hz), `video:FILE` (stamped by the file's frame
/// times, or index / rate_hz when it has none; a frame that does not decode is an unreadable
/// frame when one of the next 30 decodes, else the video has ended), `device:N` /
/// `device:/dev/videoN` and `url:URL` (stamped on arrival minus `latency_s`; a frame that does
/// not come ends them). `topic:` sources are the service's.
/// @throws InputError naming the source when it cannot be opened (or is a `topic:`).
[[nodiscard]] std::unique_ptr<FrameSource> OpenSource(const CameraConfig& camera);

}  // namespace autodrive::eye
