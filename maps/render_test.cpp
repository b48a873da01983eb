#include "maps/render.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <pugixml.hpp>

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

// Parses the XML file at `path` with pugixml into `doc`; a fatal failure when it does not parse.
void LoadXml(const fs::path& path, pugi::xml_document& doc) {
  const pugi::xml_parse_result result = doc.load_file(path.c_str());
  ASSERT_EQ(result.status, pugi::status_ok)
      << path << ": " << result.description() << " at offset " << result.offset;
}

// The children of `parent` named `name`.
std::vector<pugi::xml_node> Children(pugi::xml_node parent, const char* name) {
  std::vector<pugi::xml_node> out;
  for (pugi::xml_node child : parent.children(name)) out.push_back(child);
  return out;
}

TEST(RenderSvg, ParsesAsXmlWithOnePathPerRoadRegionAndOneSubpathPerRing) {
  for (const Layout& layout :
       {FourWay(), MakeLayout({{"curve", "curve@270"}, {"curve@90", "curve@180"}})}) {
    const Map map = Build(layout);
    const fs::path dir = TempDir("svg");
    const fs::path path = dir / "map.svg";
    RenderSvg(map, path.string());
    pugi::xml_document doc;
    ASSERT_NO_FATAL_FAILURE(LoadXml(path, doc));
    const pugi::xml_node svg = doc.document_element();
    EXPECT_STREQ(svg.name(), "svg");
    EXPECT_STREQ(svg.attribute("xmlns").value(), "http://www.w3.org/2000/svg");
    const Eigen::Vector2i size = ImageSizePx(map);
    EXPECT_EQ(svg.attribute("width").as_int(), size.x());
    EXPECT_EQ(svg.attribute("height").as_int(), size.y());
    EXPECT_EQ(std::string(svg.attribute("viewBox").value()),
              "0 0 " + std::to_string(size.x()) + " " + std::to_string(size.y()));
    // The title first, then the white background over the whole picture.
    EXPECT_STREQ(svg.first_child().name(), "title");
    const pugi::xml_node background = svg.child("rect");
    EXPECT_EQ(background.attribute("width").as_int(), size.x());
    EXPECT_STREQ(background.attribute("fill").value(), "#ffffff");

    ASSERT_GE(map.road_surface.size(), 1u);
    const std::vector<pugi::xml_node> paths = Children(svg, "path");
    EXPECT_EQ(paths.size(), map.road_surface.size());
    // Each road path has one subpath per ring (outer and holes), closed by Z.
    std::size_t rings = 0;
    for (const auto& r : map.road_surface) rings += 1 + r.holes.size();
    std::size_t subpaths = 0;
    for (const pugi::xml_node& p : paths) {
      EXPECT_STREQ(p.attribute("class").value(), "road");
      EXPECT_STREQ(p.attribute("fill-rule").value(), "evenodd");
      const std::string d = p.attribute("d").value();
      EXPECT_EQ(d.front(), 'M') << d;
      subpaths += static_cast<std::size_t>(std::count(d.begin(), d.end(), 'Z'));
    }
    EXPECT_EQ(subpaths, rings);
    EXPECT_EQ(Children(svg, "circle").size(), 3 * map.signal_heads.size());
    fs::remove_all(dir);
  }
}

TEST(RenderSvg, GivesBackAMapNameWithXmlSpecialCharactersExactly) {
  Layout layout = FourWay("stop");
  // Every character XML escapes, and an attempt to close the element and inject another.
  layout.name = "lab <A> & \"B\" 'C' ></title><script>alert(1)</script><!--";
  const Map map = Build(layout);
  const fs::path dir = TempDir("svg_name");
  const fs::path path = dir / "map.svg";
  RenderSvg(map, path.string());
  pugi::xml_document doc;
  ASSERT_NO_FATAL_FAILURE(LoadXml(path, doc));
  const pugi::xml_node svg = doc.document_element();
  const std::vector<pugi::xml_node> titles = Children(svg, "title");
  ASSERT_EQ(titles.size(), 1u);
  EXPECT_EQ(std::string(titles[0].text().get()), layout.name);
  // The legend above the map: the name and the grid.
  std::vector<std::string> texts;
  for (const pugi::xml_node& t : Children(svg, "text")) texts.emplace_back(t.text().get());
  EXPECT_EQ(texts.size(), map.signs.size() + 2);  // a letter per sign, the legend, the scale
  EXPECT_NE(std::find(texts.begin(), texts.end(), layout.name + "  (3 x 3 tiles of 1 m)"),
            texts.end());
  EXPECT_TRUE(
      doc.find_node([](pugi::xml_node n) { return std::string(n.name()) == "script"; }).empty());
  fs::remove_all(dir);
}

TEST(RenderSvg, RefusesAMapNameWithAControlCharacterAndWritesNothing) {
  Layout layout = FourWay();
  layout.name = "lab\x01one";
  const Map map = Build(layout);
  const fs::path dir = TempDir("svg_control");
  const fs::path path = dir / "map.svg";
  EXPECT_EQ(test::ErrorMessage([&] { RenderSvg(map, path.string()); }),
            "the text of <title> \"lab\\x01one\" holds the control character 0x01, which XML "
            "cannot carry");
  EXPECT_FALSE(fs::exists(path));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace autodrive::maps
