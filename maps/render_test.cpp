#include "maps/render.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/test_layouts.h"

namespace autodrive::maps {
namespace {

namespace fs = std::filesystem;

Layout MakeLayout(const std::vector<std::vector<std::string>>& rows) {
  return maps::MakeLayout("test", rows);
}

using test_layouts::FourWay;

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("autodrive_render_test_" + name + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

// The colours the renderer documents, as OpenCV reads them (blue, green, red).
const cv::Vec3b kGround(188, 212, 196);
const cv::Vec3b kRoad(64, 64, 64);
const cv::Vec3b kWhite(245, 245, 245);
const cv::Vec3b kAmber(0, 176, 255);
const cv::Vec3b kBox(0, 140, 255);

// The pixel under the map-frame point p_M.
cv::Vec3b PixelAt(const cv::Mat& image, const Map& map, const Eigen::Vector2d& p_M,
                  const RenderOptions& options = {}) {
  const Eigen::Vector2d uv = MapToPixel(map, options, p_M);
  return image.at<cv::Vec3b>(static_cast<int>(std::floor(uv.y())),
                             static_cast<int>(std::floor(uv.x())));
}

// The point a quarter of the way along a polyline (by index; samples are evenly spaced).
Eigen::Vector2d QuarterWay(const Polyline& p) { return p[p.size() / 4]; }

TEST(RenderPng, MapsTheMapFrameWithNorthUpInsideTheMargins) {
  const Map map = Build(FourWay());
  const RenderOptions options;
  EXPECT_EQ(ImageSizePx(map, options), Eigen::Vector2i(3 * 120 + 80, 3 * 120 + 80));
  EXPECT_EQ(MapToPixel(map, options, {0, 0}), Eigen::Vector2d(40, 400));
  EXPECT_EQ(MapToPixel(map, options, {3, 3}), Eigen::Vector2d(400, 40));
  RenderOptions big;
  big.pixels_per_tile = 50;
  big.margin_px = 0;
  EXPECT_EQ(ImageSizePx(Build(MakeLayout({{"straight", "straight"}})), big),
            Eigen::Vector2i(100, 50));
}

TEST(RenderPng, DrawsRoadsGroundStopLinesAndSignalHeads) {
  const Map map = Build(FourWay());
  const fs::path dir = TempDir("png");
  const fs::path path = dir / "four_way.png";
  RenderPng(map, path.string());
  const cv::Mat image = cv::imread(path.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 440);
  EXPECT_EQ(image.rows, 440);

  for (const Lane& lane : map.lanes) {
    EXPECT_EQ(PixelAt(image, map, QuarterWay(lane.centreline)), kRoad) << lane.name;
  }
  // The empty corner tiles are ground, away from the heads at the intersection's corners.
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(0.3, 0.3), Eigen::Vector2d(2.7, 2.7),
                                   Eigen::Vector2d(0.5, 2.5), Eigen::Vector2d(2.5, 0.5)}) {
    EXPECT_EQ(PixelAt(image, map, p), kGround) << p.transpose();
  }
  int stop_lines = 0;
  for (const Lane& lane : map.lanes) {
    if (!lane.stop_line) continue;
    ++stop_lines;
    const Eigen::Vector2d mid = (lane.stop_line->left + lane.stop_line->right) / 2;
    EXPECT_EQ(PixelAt(image, map, mid), kWhite) << lane.name;
  }
  EXPECT_EQ(stop_lines, 4);
  ASSERT_EQ(map.signal_heads.size(), 4u);
  for (const SignalHead& h : map.signal_heads) {
    EXPECT_EQ(PixelAt(image, map, h.X_MH.translation()), kAmber);
  }
  // A movement path inside the intersection is drawn in a colour that is neither road nor
  // ground.
  const Movement& m = map.movements.front();
  const cv::Vec3b on_path = PixelAt(image, map, m.path[m.path.size() / 2]);
  EXPECT_NE(on_path, kRoad);
  EXPECT_NE(on_path, kGround);
  fs::remove_all(dir);
}

TEST(RenderPng, NorthIsUp) {
  const Map map = Build(MakeLayout({{"straight"}, {"empty"}}));
  const fs::path dir = TempDir("north");
  RenderPng(map, (dir / "north.png").string());
  const cv::Mat image = cv::imread((dir / "north.png").string(), cv::IMREAD_COLOR);
  ASSERT_EQ(image.rows, 2 * 120 + 80);
  // The road's lanes are 0.15 m either side of y = 1.5: image rows 40 + 60 -+ 18.
  EXPECT_EQ(image.at<cv::Vec3b>(40 + 60 - 18, 40 + 30), kRoad);
  EXPECT_EQ(image.at<cv::Vec3b>(40 + 60 + 18, 40 + 30), kRoad);
  EXPECT_EQ(image.at<cv::Vec3b>(40 + 180, 40 + 30), kGround);
  fs::remove_all(dir);
}

TEST(RenderPng, DrawsObstaclesAndStopSigns) {
  Layout layout = FourWay("stop");
  layout.obstacles = {{"box", 0.5, 1.5, 0.0, 0.2, 0.2, 0.2}};
  const Map map = Build(layout);
  const fs::path dir = TempDir("signs");
  RenderPng(map, (dir / "signs.png").string());
  const cv::Mat image = cv::imread((dir / "signs.png").string(), cv::IMREAD_COLOR);
  EXPECT_EQ(PixelAt(image, map, {0.5, 1.5}), kBox);
  ASSERT_EQ(map.signs.size(), 4u);
  for (const Sign& sign : map.signs) {
    // The octagon (radius 8 px, ~200 px) is red around its white letter.
    const Eigen::Vector2d uv = MapToPixel(map, {}, sign.X_MS.translation());
    int red = 0;
    for (int dv = -7; dv <= 7; ++dv) {
      for (int du = -7; du <= 7; ++du) {
        const cv::Vec3b px =
            image.at<cv::Vec3b>(static_cast<int>(uv.y()) + dv, static_cast<int>(uv.x()) + du);
        red += px[2] > 180 && px[1] < 90 && px[0] < 90 ? 1 : 0;
      }
    }
    EXPECT_GT(red, 80) << sign.X_MS;
  }
  fs::remove_all(dir);
}

TEST(RenderPng, BadOptionsAndUnwritablePathsThrow) {
  const Map map = Build(FourWay());
  RenderOptions o;
  o.pixels_per_tile = 2;
  EXPECT_EQ(test::ErrorMessage([&] { RenderPng(map, "/tmp/x.png", o); }),
            "pixels_per_tile must be in [8, 1000], got 2");
  o = {};
  o.margin_px = -1;
  EXPECT_EQ(test::ErrorMessage([&] { RenderSvg(map, "/tmp/x.svg", o); }),
            "margin_px must be in [0, 500], got -1");
  o = {};
  o.pixels_per_tile = 1000;
  Map wide = map;
  wide.cols = 40;
  EXPECT_EQ(test::ErrorMessage([&] { (void)ImageSizePx(wide, o); }),
            "the picture of map \"four_way\" would be 40080 x 3080 px, more than 30000 px a "
            "side; lower pixels_per_tile (1000)");

  const fs::path dir = TempDir("unwritable");
  const std::string png = (dir / "missing" / "a.png").string();
  EXPECT_EQ(test::ErrorMessage([&] { RenderPng(map, png); }),
            "cannot write the PNG picture \"" + png + "\": No such file or directory");
  const std::string svg = (dir / "missing" / "a.svg").string();
  EXPECT_EQ(test::ErrorMessage([&] { RenderSvg(map, svg); }),
            "cannot write the SVG picture \"" + svg + "\": No such file or directory");
  fs::remove_all(dir);
}

std::size_t Count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t pos = text.find(what); pos != std::string::npos;
       pos = text.find(what, pos + what.size())) {
    ++n;
  }
  return n;
}

// Checks that the tags nest: every <x ...> is closed by </x> in order or is self-closing.
// Returns "" or what is wrong.
std::string CheckTagsNest(const std::string& xml) {
  std::vector<std::string> open;
  std::size_t pos = 0;
  while ((pos = xml.find('<', pos)) != std::string::npos) {
    const std::size_t end = xml.find('>', pos);
    if (end == std::string::npos) return "unterminated tag at " + std::to_string(pos);
    const std::string tag = xml.substr(pos + 1, end - pos - 1);
    pos = end + 1;
    if (tag.empty()) return "empty tag";
    if (tag.front() == '?' || tag.front() == '!') continue;
    if (tag.find('<') != std::string::npos) return "'<' inside tag " + tag;
    if (tag.back() == '/') continue;
    const std::string name =
        tag.substr(tag.front() == '/' ? 1 : 0, tag.find(' ') - (tag.front() == '/' ? 1 : 0));
    if (tag.front() == '/') {
      if (open.empty() || open.back() != name) return "unexpected </" + name + ">";
      open.pop_back();
    } else {
      open.push_back(name);
    }
  }
  return open.empty() ? "" : "unclosed <" + open.back() + ">";
}

TEST(RenderSvg, HasOnePathPerRoadRegionTheNameAndNestedTags) {
  for (const Layout& base :
       {FourWay(), MakeLayout({{"curve", "curve@270"}, {"curve@90", "curve@180"}})}) {
    Layout layout = base;
    layout.name = "lab <A> & \"B\"";
    const Map map = Build(layout);
    const fs::path dir = TempDir("svg");
    const fs::path path = dir / "map.svg";
    RenderSvg(map, path.string());
    std::ifstream in(path);
    const std::string svg((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
    const Eigen::Vector2i size = ImageSizePx(map);
    EXPECT_NE(svg.find("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" +
                       std::to_string(size.x()) + "\" height=\"" + std::to_string(size.y()) + "\""),
              std::string::npos);
    EXPECT_EQ(CheckTagsNest(svg), "");
    ASSERT_GE(map.road_surface.size(), 1u);
    EXPECT_EQ(Count(svg, "<path"), map.road_surface.size());
    EXPECT_EQ(Count(svg, "<path class=\"road\""), map.road_surface.size());
    // Each road path has one subpath per ring (outer and holes).
    std::size_t rings = 0;
    for (const auto& r : map.road_surface) rings += 1 + r.holes.size();
    EXPECT_EQ(Count(svg, "Z "), rings);
    EXPECT_EQ(Count(svg, "<title>lab &lt;A&gt; &amp; &quot;B&quot;</title>"), 1u);
    EXPECT_EQ(Count(svg, ">lab &lt;A&gt; &amp; &quot;B&quot;  (2 x 2 tiles"),
              base.grid.size() == 2 ? 1u : 0u);
    EXPECT_EQ(Count(svg, "<circle"), 3 * map.signal_heads.size());
    fs::remove_all(dir);
  }
}

}  // namespace
}  // namespace autodrive::maps
