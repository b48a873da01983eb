// Where frames come from: an unreadable frame (a corrupt image file, a 16-bit image, a video's
// frame that does not decode) comes as such, named, with its index and stamp, and the source
// goes on with the next.
#include "eye/sources.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "common/test_support.h"

namespace autodrive::eye {
namespace {

namespace fs = std::filesystem;

CameraConfig Camera(const std::string& source) {
  return {"overhead", source, "camera.yaml", std::nullopt, 10.0, 0.0};
}

// A frame whose middle pixel tells its number.
cv::Mat Numbered(int i) { return cv::Mat(120, 160, CV_8UC3, cv::Scalar(8 * i + 4, 100, 50)); }
int Number(const cv::Mat& image) { return image.at<cv::Vec3b>(60, 80)[0] / 8; }

TEST(ImageFolder, AnUnreadableFileIsAFrameWithoutAnImageThatSaysWhyAndTheNextFollow) {
  const test::TempDir dir("eye_sources_images");
  for (int i = 0; i < 6; ++i) {
    ASSERT_TRUE(
        cv::imwrite((dir.path() / ("f" + std::to_string(i) + ".png")).string(), Numbered(i)));
  }
  fs::resize_file(dir.path() / "f2.png", 100);  // cut short
  ASSERT_TRUE(cv::imwrite((dir.path() / "f4.png").string(), cv::Mat(120, 160, CV_16UC1, 1000)));
  const auto source = OpenSource(Camera("images:" + dir.str()));
  std::vector<std::string> unreadable;
  for (int i = 0; i < 6; ++i) {
    const auto frame = source->Next();
    ASSERT_TRUE(frame.has_value()) << i;
    EXPECT_EQ(frame->index, i);
    EXPECT_EQ(frame->name, "f" + std::to_string(i) + ".png");
    EXPECT_NEAR(ToSeconds(frame->stamp), i / 10.0, 1e-9);
    if (frame->unreadable.empty()) {
      EXPECT_EQ(Number(frame->image), i);
    } else {
      EXPECT_TRUE(frame->image.empty());
      unreadable.push_back(frame->name + ": " + frame->unreadable);
    }
  }
  EXPECT_FALSE(source->Next().has_value());
  EXPECT_EQ(unreadable, (std::vector<std::string>{
                            "f2.png: not an image OpenCV can read (a corrupt or truncated file?)",
                            "f4.png: not an 8-bit grey, BGR or BGRA image"}));
}

TEST(VideoFile, AFrameThatDoesNotDecodeIsSkippedAndTheVideoGoesOnToItsEnd) {
  const test::TempDir dir("eye_sources_video");
  const fs::path file = dir.path() / "clip.avi";
  {
    cv::VideoWriter writer(file.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0,
                           cv::Size(160, 120));
    ASSERT_TRUE(writer.isOpened()) << "OpenCV cannot write MJPG into AVI here";
    for (int i = 0; i < 20; ++i) writer.write(Numbered(i));
  }
  // Frame 10's JPEG data (from its start-of-image marker) overwritten with zeros.
  std::vector<char> bytes;
  {
    std::ifstream in(file, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  int images = 0;
  for (std::size_t i = 0; i + 1 < bytes.size(); ++i) {
    if (static_cast<unsigned char>(bytes[i]) == 0xFF &&
        static_cast<unsigned char>(bytes[i + 1]) == 0xD8 && images++ == 10) {
      for (std::size_t k = i; k < i + 200 && k < bytes.size(); ++k) bytes[k] = 0;
      break;
    }
  }
  ASSERT_EQ(images, 11);
  std::ofstream(file, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));

  const auto source = OpenSource(Camera("video:" + file.string()));
  std::vector<int> numbers;
  int unreadable = 0;
  while (const auto frame = source->Next()) {
    if (!frame->unreadable.empty()) {
      ++unreadable;
      EXPECT_EQ(frame->name, "frame 10");
      EXPECT_EQ(frame->unreadable, "does not decode");
      continue;
    }
    numbers.push_back(Number(frame->image));
  }
  EXPECT_EQ(unreadable, 1);
  std::vector<int> expected;
  for (int i = 0; i < 20; ++i) {
    if (i != 10) expected.push_back(i);
  }
  EXPECT_EQ(numbers, expected);
}

}  // namespace
}  // namespace autodrive::eye
