#include "maps/render.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "maps/internal/xml.h"

namespace autodrive::maps {

namespace {

using Vec = Eigen::Vector2d;
// Points in continuous pixel coordinates (u right, v down).
using Points = std::vector<Vec>;

constexpr int kMaxSidePx = 30000;

struct Colour {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
};

constexpr Colour kBackground{255, 255, 255};
constexpr Colour kGround{196, 212, 188};
constexpr Colour kGrid{176, 192, 168};
constexpr Colour kRoad{64, 64, 64};
constexpr Colour kWhite{245, 245, 245};
constexpr Colour kYellow{240, 200, 40};
constexpr Colour kArrow{160, 160, 160};
constexpr Colour kBox{255, 140, 0};
constexpr Colour kBoxEdge{150, 80, 0};
constexpr Colour kWall{128, 128, 128};
constexpr Colour kWallEdge{70, 70, 70};
constexpr Colour kHeadBody{25, 25, 25};
constexpr Colour kRed{220, 30, 30};
constexpr Colour kAmber{255, 176, 0};
constexpr Colour kGreen{30, 200, 60};
constexpr Colour kBlue{30, 80, 200};
constexpr Colour kText{20, 20, 20};

Colour TurnColour(Turn turn) {
  switch (turn) {
    case Turn::kStraight:
      return {0, 170, 255};
    case Turn::kLeft:
      return {230, 0, 200};
    case Turn::kRight:
      return {0, 220, 120};
    case Turn::kUTurn:
      return {255, 160, 0};
  }
  return kWhite;
}

// ---- Canvases: the scene is drawn once, onto an OpenCV image or into SVG text --------------

class Canvas {
 public:
  virtual ~Canvas() = default;
  // An axis-aligned filled rectangle [min, max).
  virtual void Rect(const Vec& min, const Vec& max, Colour fill) = 0;
  // Disjoint regions (they may share edges), each its rings (an outer boundary and its holes)
  // by the even-odd rule.
  virtual void FillRegions(const std::vector<std::vector<Points>>& regions, Colour fill,
                           std::string_view cls) = 0;
  virtual void Line(const Points& points, Colour colour, double width_px, bool closed) = 0;
  virtual void Polygon(const Points& points, Colour fill, std::optional<Colour> stroke,
                       double stroke_px) = 0;
  virtual void Circle(const Vec& centre, double radius_px, Colour fill,
                      std::optional<Colour> stroke, double stroke_px) = 0;
  // Text whose vertical middle is at `at.y()`, starting at (or centred on) `at.x()`.
  virtual void Text(const Vec& at, const std::string& text, double height_px, Colour colour,
                    bool centred) = 0;
};

class CvCanvas final : public Canvas {
 public:
  CvCanvas(int width, int height, Colour background, bool antialias)
      : image_(height, width, CV_8UC3, Scalar(background)),
        line_type_(antialias ? cv::LINE_AA : cv::LINE_8) {}
  [[nodiscard]] const cv::Mat& image() const { return image_; }

  void Rect(const Vec& min, const Vec& max, Colour fill) override {
    const cv::Point a(static_cast<int>(std::lround(min.x())),
                      static_cast<int>(std::lround(min.y())));
    const cv::Point b(static_cast<int>(std::lround(max.x())) - 1,
                      static_cast<int>(std::lround(max.y())) - 1);
    cv::rectangle(image_, a, b, Scalar(fill), cv::FILLED);
  }
  void FillRegions(const std::vector<std::vector<Points>>& regions, Colour fill,
                   std::string_view) override {
    // One fill of all the rings: the regions are disjoint, so even-odd gives their union.
    std::vector<std::vector<cv::Point>> contours;
    for (const auto& rings : regions) {
      for (const auto& ring : rings) contours.push_back(ToCv(ring));
    }
    cv::fillPoly(image_, contours, Scalar(fill), line_type_, kShift);
  }
  void Line(const Points& points, Colour colour, double width_px, bool closed) override {
    if (points.size() < 2) return;
    const std::vector<std::vector<cv::Point>> lines{ToCv(points)};
    cv::polylines(image_, lines, closed, Scalar(colour), Thickness(width_px), line_type_, kShift);
  }
  void Polygon(const Points& points, Colour fill, std::optional<Colour> stroke,
               double stroke_px) override {
    const std::vector<std::vector<cv::Point>> contours{ToCv(points)};
    cv::fillPoly(image_, contours, Scalar(fill), line_type_, kShift);
    if (stroke) {
      cv::polylines(image_, contours, true, Scalar(*stroke), Thickness(stroke_px), line_type_,
                    kShift);
    }
  }
  void Circle(const Vec& centre, double radius_px, Colour fill, std::optional<Colour> stroke,
              double stroke_px) override {
    const int r = static_cast<int>(std::lround(radius_px * (1 << kShift)));
    cv::circle(image_, ToCv(centre), r, Scalar(fill), cv::FILLED, line_type_, kShift);
    if (stroke) {
      cv::circle(image_, ToCv(centre), r, Scalar(*stroke), Thickness(stroke_px), line_type_,
                 kShift);
    }
  }
  void Text(const Vec& at, const std::string& text, double height_px, Colour colour,
            bool centred) override {
    constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
    const int thickness = height_px >= 14 ? 2 : 1;
    const double scale =
        cv::getFontScaleFromHeight(kFont, static_cast<int>(std::lround(height_px)), thickness);
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, kFont, scale, thickness, &baseline);
    const double x = centred ? at.x() - size.width / 2.0 : at.x();
    const cv::Point origin(static_cast<int>(std::lround(x)),
                           static_cast<int>(std::lround(at.y() + size.height / 2.0)));
    cv::putText(image_, text, origin, kFont, scale, Scalar(colour), thickness, line_type_);
  }

 private:
  static constexpr int kShift = 4;  // sub-pixel bits of the coordinates given to OpenCV

  static cv::Scalar Scalar(Colour c) {
    return {static_cast<double>(c.b), static_cast<double>(c.g), static_cast<double>(c.r)};
  }
  static int Thickness(double width_px) {
    return std::max(1, static_cast<int>(std::lround(width_px)));
  }
  // OpenCV's integer coordinate i is the centre of pixel i, at i + 0.5 in ours.
  static cv::Point ToCv(const Vec& p) {
    constexpr double kScale = 1 << kShift;
    return {static_cast<int>(std::lround((p.x() - 0.5) * kScale)),
            static_cast<int>(std::lround((p.y() - 0.5) * kScale))};
  }
  static std::vector<cv::Point> ToCv(const Points& points) {
    std::vector<cv::Point> out;
    out.reserve(points.size());
    for (const auto& p : points) out.push_back(ToCv(p));
    return out;
  }

  cv::Mat image_;
  int line_type_;
};

std::string Num(double v) {
  char buffer[64];
  const auto [end, ec] =
      std::to_chars(buffer, buffer + sizeof(buffer), v, std::chars_format::fixed, 2);
  AUTODRIVE_CHECK(ec == std::errc());
  std::string s(buffer, end);
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s == "-0" ? "0" : s;
}

std::string Hex(Colour c) {
  constexpr std::string_view kDigits = "0123456789abcdef";
  std::string s = "#";
  for (std::uint8_t v : {c.r, c.g, c.b}) {
    s += kDigits[v >> 4];
    s += kDigits[v & 15];
  }
  return s;
}

// The SVG as a pugixml document: one element per drawing call, in drawing order, all children
// of `<svg>`; pugixml escapes the text and attribute values.
class SvgCanvas final : public Canvas {
 public:
  // Throws InputError when the title holds a character XML cannot carry.
  SvgCanvas(int width, int height, const std::string& title) {
    internal::AddXmlDeclaration(doc_);
    const std::string w = std::to_string(width);
    const std::string h = std::to_string(height);
    svg_ = internal::AppendElement(doc_, "svg",
                                   {{"xmlns", "http://www.w3.org/2000/svg"},
                                    {"width", w},
                                    {"height", h},
                                    {"viewBox", "0 0 " + w + " " + h}});
    internal::SetText(internal::AppendElement(svg_, "title"), title);
    Rect(Vec(0.0, 0.0), Vec(static_cast<double>(width), static_cast<double>(height)), kBackground);
  }
  SvgCanvas(const SvgCanvas&) = delete;
  SvgCanvas& operator=(const SvgCanvas&) = delete;

  // The document as text, two spaces of indentation per level.
  [[nodiscard]] std::string Xml() const { return internal::XmlText(doc_, "  "); }

  void Rect(const Vec& min, const Vec& max, Colour fill) override {
    internal::AppendElement(svg_, "rect",
                            {{"x", Num(min.x())},
                             {"y", Num(min.y())},
                             {"width", Num(max.x() - min.x())},
                             {"height", Num(max.y() - min.y())},
                             {"fill", Hex(fill)}});
  }
  void FillRegions(const std::vector<std::vector<Points>>& regions, Colour fill,
                   std::string_view cls) override {
    // One path per region; a hairline stroke of the fill's colour hides the seams viewers
    // leave between anti-aliased neighbours.
    for (const auto& rings : regions) {
      std::string d;
      for (const auto& ring : rings) {
        for (std::size_t i = 0; i < ring.size(); ++i) {
          d += (i == 0 ? "M" : "L") + Num(ring[i].x()) + "," + Num(ring[i].y()) + " ";
        }
        d += "Z ";
      }
      internal::AppendElement(svg_, "path",
                              {{"class", std::string(cls)},
                               {"fill", Hex(fill)},
                               {"stroke", Hex(fill)},
                               {"stroke-width", "0.5"},
                               {"fill-rule", "evenodd"},
                               {"d", d}});
    }
  }
  void Line(const Points& points, Colour colour, double width_px, bool closed) override {
    if (points.size() < 2) return;
    internal::AppendElement(svg_, closed ? "polygon" : "polyline",
                            {{"points", PointList(points)},
                             {"fill", "none"},
                             {"stroke", Hex(colour)},
                             {"stroke-width", Num(std::max(1.0, width_px))}});
  }
  void Polygon(const Points& points, Colour fill, std::optional<Colour> stroke,
               double stroke_px) override {
    pugi::xml_node polygon = internal::AppendElement(
        svg_, "polygon", {{"points", PointList(points)}, {"fill", Hex(fill)}});
    if (stroke) AppendStroke(polygon, *stroke, stroke_px);
  }
  void Circle(const Vec& centre, double radius_px, Colour fill, std::optional<Colour> stroke,
              double stroke_px) override {
    pugi::xml_node circle = internal::AppendElement(svg_, "circle",
                                                    {{"cx", Num(centre.x())},
                                                     {"cy", Num(centre.y())},
                                                     {"r", Num(radius_px)},
                                                     {"fill", Hex(fill)}});
    if (stroke) AppendStroke(circle, *stroke, stroke_px);
  }
  void Text(const Vec& at, const std::string& text, double height_px, Colour colour,
            bool centred) override {
    // The font size is about 1.4 times the height of a capital letter.
    pugi::xml_node element = internal::AppendElement(svg_, "text",
                                                     {{"x", Num(at.x())},
                                                      {"y", Num(at.y())},
                                                      {"font-family", "sans-serif"},
                                                      {"font-size", Num(height_px * 1.4)},
                                                      {"dominant-baseline", "central"},
                                                      {"text-anchor", centred ? "middle" : "start"},
                                                      {"fill", Hex(colour)}});
    internal::SetText(element, text);
  }

 private:
  static std::string PointList(const Points& points) {
    std::string s;
    for (const auto& p : points) s += Num(p.x()) + "," + Num(p.y()) + " ";
    if (!s.empty()) s.pop_back();
    return s;
  }
  static void AppendStroke(pugi::xml_node element, Colour stroke, double stroke_px) {
    internal::AppendAttribute(element, "stroke", Hex(stroke));
    internal::AppendAttribute(element, "stroke-width", Num(stroke_px));
  }

  pugi::xml_document doc_;
  pugi::xml_node svg_;
};

// ---- Geometry along polylines (map frame) ---------------------------------------------------

std::vector<double> ArcLengths(const Polyline& p) {
  std::vector<double> s(p.size(), 0.0);
  for (std::size_t i = 1; i < p.size(); ++i) s[i] = s[i - 1] + (p[i] - p[i - 1]).norm();
  return s;
}

// The point at arc length `s` and the unit tangent there. Precondition: two or more points.
std::pair<Vec, Vec> PointAt(const Polyline& p, const std::vector<double>& arc, double s) {
  std::size_t i = 1;
  while (i + 1 < p.size() && arc[i] < s) ++i;
  const Vec d = p[i] - p[i - 1];
  const double len = arc[i] - arc[i - 1];
  const double t = len > 0 ? std::clamp((s - arc[i - 1]) / len, 0.0, 1.0) : 0.0;
  const Vec tangent = len > 0 ? Vec(d / len) : Vec(1, 0);
  return {p[i - 1] + d * t, tangent};
}

// The part of `p` between arc lengths s0 < s1.
Polyline Between(const Polyline& p, const std::vector<double>& arc, double s0, double s1) {
  Polyline out{PointAt(p, arc, s0).first};
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (arc[i] > s0 && arc[i] < s1) out.push_back(p[i]);
  }
  out.push_back(PointAt(p, arc, s1).first);
  return out;
}

// Dashes of `on_m` separated by gaps of `off_m`, starting with half a gap. The polyline is
// first put in a canonical direction so that the two lanes sharing a line dash it alike.
std::vector<Polyline> Dashes(Polyline p, double on_m, double off_m) {
  std::vector<Polyline> out;
  if (p.size() < 2) return out;
  const Vec d = p.back() - p.front();
  if (d.x() < -1e-9 || (std::abs(d.x()) <= 1e-9 && d.y() < 0)) std::reverse(p.begin(), p.end());
  const std::vector<double> arc = ArcLengths(p);
  for (double s = off_m / 2; s < arc.back(); s += on_m + off_m) {
    out.push_back(Between(p, arc, s, std::min(s + on_m, arc.back())));
  }
  return out;
}

// ---- The scene ------------------------------------------------------------------------------

class Scene {
 public:
  Scene(const Map& map, const RenderOptions& options, Canvas& canvas)
      : map_(map), o_(options), canvas_(canvas), s_(options.pixels_per_tile / map.tile_size_m) {}

  void Draw() {
    DrawGround();
    DrawRoad();
    DrawParkingBays();
    DrawLaneMarkings();
    if (o_.ground_only) {
      DrawStopLines();
      return;
    }
    if (o_.show_movements) DrawMovements();
    if (o_.show_lane_arrows) DrawArrows();
    DrawStopLines();
    DrawObstacles();
    if (o_.show_signal_heads) DrawSignalHeads();
    DrawSigns();
    DrawLegend();
  }

 private:
  Vec P(const Vec& p_M) const { return MapToPixel(map_, o_, p_M); }
  Points P(const Polyline& line) const {
    Points out;
    out.reserve(line.size());
    for (const auto& p : line) out.push_back(P(p));
    return out;
  }
  // A width in metres as pixels, at least `min_px`.
  double Px(double m, double min_px = 1.0) const { return std::max(min_px, m * s_); }

  void DrawGround() {
    const Vec lo = P(Vec(0, map_.size_m().y()));
    const Vec hi = P(Vec(map_.size_m().x(), 0));
    canvas_.Rect(lo, hi, kGround);
    if (!o_.show_tile_grid || o_.ground_only) return;
    const double t = map_.tile_size_m;
    for (int c = 0; c <= map_.cols; ++c) {
      canvas_.Line({P(Vec(c * t, 0)), P(Vec(c * t, map_.rows * t))}, kGrid, 1.0, false);
    }
    for (int r = 0; r <= map_.rows; ++r) {
      canvas_.Line({P(Vec(0, r * t)), P(Vec(map_.cols * t, r * t))}, kGrid, 1.0, false);
    }
  }

  void DrawRoad() {
    std::vector<std::vector<Points>> regions;
    for (const Region& region : map_.road_surface) {
      std::vector<Points>& rings = regions.emplace_back();
      rings.push_back(P(region.outer));
      for (const auto& hole : region.holes) rings.push_back(P(hole));
    }
    canvas_.FillRegions(regions, kRoad, "road");
    if (o_.ground_only) {
      // The regions of neighbouring tiles and of lanes meet with slivers and small wedges
      // between them (curves are polylines); from a camera low over the road they show as
      // lines. Every region is grown by 1.5 mm: its edges are under the kerb lines or at
      // open corners, where the difference does not show.
      for (const auto& rings : regions) {
        for (const auto& ring : rings) canvas_.Line(ring, kRoad, Px(0.003), true);
      }
    }
  }

  void DrawParkingBays() {
    for (const auto& bay : map_.parking_bays) {
      canvas_.Line(P(bay.footprint), kWhite, Px(0.01), true);
    }
  }

  // Solid white along the kerb, dashed white between lanes of one direction, dashed yellow
  // between opposite directions (the left boundary of lanes next to the centreline).
  void DrawLaneMarkings() {
    const auto group = [](const Lane& lane) { return lane.name.substr(0, lane.name.rfind(':')); };
    std::map<std::string, int> kerb_index;
    for (const auto& lane : map_.lanes) {
      int& k = kerb_index.try_emplace(group(lane), 0).first->second;
      k = std::max(k, lane.index_from_centre);
    }
    const double width = Px(0.015, 2.0);
    for (const auto& lane : map_.lanes) {
      if (OnParkingTile(lane)) continue;  // an open area: its bays are its markings
      if (lane.index_from_centre == kerb_index[group(lane)]) {
        canvas_.Line(P(lane.right_boundary), kWhite, width, false);
      }
      const Colour colour = lane.index_from_centre == 0 ? kYellow : kWhite;
      for (const auto& dash : Dashes(lane.left_boundary, 0.06, 0.06)) {
        canvas_.Line(P(dash), colour, width, false);
      }
    }
  }

  bool OnParkingTile(const Lane& lane) const {
    const auto row = static_cast<std::size_t>(lane.tile.row);
    const auto col = static_cast<std::size_t>(lane.tile.col);
    return row < map_.cells.size() && col < map_.cells[row].size() &&
           map_.cells[row][col].type == ModuleType::kParking;
  }

  void DrawMovements() {
    for (const auto& m : map_.movements) canvas_.Line(P(m.path), TurnColour(m.turn), 1.0, false);
  }

  void DrawArrows() {
    for (const auto& lane : map_.lanes) {
      if (lane.centreline.size() < 2) continue;
      const std::vector<double> arc = ArcLengths(lane.centreline);
      const auto [mid, t] = PointAt(lane.centreline, arc, arc.back() / 2);
      const Vec n(-t.y(), t.x());
      const Vec tip = mid + t * 0.06;
      const Vec base = tip - t * 0.04;
      canvas_.Line({P(Vec(mid - t * 0.06)), P(base)}, kArrow, Px(0.012, 1.5), false);
      canvas_.Polygon({P(tip), P(Vec(base + n * 0.025)), P(Vec(base - n * 0.025))}, kArrow,
                      std::nullopt, 0);
    }
  }

  void DrawStopLines() {
    for (const auto& lane : map_.lanes) {
      if (!lane.stop_line) continue;
      canvas_.Line({P(lane.stop_line->left), P(lane.stop_line->right)}, kWhite, Px(0.04, 3.0),
                   false);
    }
  }

  void DrawObstacles() {
    for (const auto& o : map_.obstacles) {
      const bool wall = o.kind == "wall";
      canvas_.Polygon(P(o.footprint), wall ? kWall : kBox, wall ? kWallEdge : kBoxEdge, 1.0);
    }
  }

  // A dark body along the head's y axis with red, amber and green lamps; amber at its origin.
  void DrawSignalHeads() {
    const double r_m = Px(0.018, 3.0) / s_;
    for (const auto& h : map_.signal_heads) {
      const Vec c = h.X_MH.translation();
      const Vec x(h.X_MH.cos_yaw(), h.X_MH.sin_yaw());
      const Vec y(-x.y(), x.x());
      const double a = 1.5 * r_m;
      const double b = 3.9 * r_m;
      canvas_.Polygon({P(Vec(c + x * a + y * b)), P(Vec(c - x * a + y * b)),
                       P(Vec(c - x * a - y * b)), P(Vec(c + x * a - y * b))},
                      kHeadBody, std::nullopt, 0);
      const std::array<std::pair<double, Colour>, 3> lamps{
          {{2.4, kRed}, {0.0, kAmber}, {-2.4, kGreen}}};
      for (const auto& [offset, colour] : lamps) {
        canvas_.Circle(P(Vec(c + y * (offset * r_m))), r_m * s_, colour, std::nullopt, 0);
      }
      // Its id (signal_<id>, what the lights files list), behind it, away from the traffic.
      canvas_.Text(P(Vec(c - x * (4.5 * r_m))), std::to_string(h.id.value()),
                   std::max(8.0, 3.0 * r_m * s_), kText, true);
    }
  }

  static std::string Letter(const Sign& sign) {
    static const std::map<std::string, std::string, std::less<>> kLetters{
        {"stop", "S"},        {"yield", "Y"},   {"speed_limit", "V"},
        {"no_entry", "N"},    {"parking", "P"}, {"curve_left", "L"},
        {"curve_right", "R"}, {"one_way", "O"}, {"pedestrian_crossing", "X"}};
    const auto it = kLetters.find(sign.type);
    if (it != kLetters.end()) return it->second;
    return sign.type.empty()
               ? "?"
               : std::string(
                     1, static_cast<char>(std::toupper(static_cast<unsigned char>(sign.type[0]))));
  }

  void DrawSigns() {
    const double r = Px(0.06, 8.0);
    for (const auto& sign : map_.signs) {
      const Vec c = P(sign.X_MS.translation());
      const std::string letter = Letter(sign);
      Colour text = kWhite;
      if (sign.type == "stop") {
        Points octagon;
        for (int k = 0; k < 8; ++k) {
          const double angle = kPi / 8 + k * kPi / 4;
          octagon.push_back(c + r * Vec(std::cos(angle), std::sin(angle)));
        }
        canvas_.Polygon(octagon, kRed, kWhite, 1.0);
      } else if (sign.type == "yield") {
        // Point down, as the real sign.
        const Points triangle{c + r * Vec(-1.0, -0.6), c + r * Vec(1.0, -0.6), c + r * Vec(0, 1.1)};
        canvas_.Polygon(triangle, kWhite, kRed, 2.0);
        text = kRed;
      } else if (sign.type == "parking" || sign.type == "one_way" ||
                 sign.type == "pedestrian_crossing") {
        canvas_.Circle(c, r, kBlue, kWhite, 1.0);
      } else if (sign.type == "no_entry") {
        canvas_.Circle(c, r, kRed, kWhite, 1.0);
      } else {
        canvas_.Circle(c, r, kWhite, kRed, 2.0);
        text = kText;
      }
      canvas_.Text(c, letter, r, text, true);
    }
  }

  // The map's name above the map and a scale bar below it, in the margins.
  void DrawLegend() {
    const double m = o_.margin_px;
    if (m < 12) return;
    const double map_w_px = map_.cols * o_.pixels_per_tile;
    const double map_h_px = map_.rows * o_.pixels_per_tile;
    std::ostringstream title;
    title << map_.name << "  (" << map_.cols << " x " << map_.rows << " tiles of "
          << map_.tile_size_m << " m)";
    const double text_px = std::clamp(m * 0.35, 8.0, 20.0);
    canvas_.Text(Vec(m, m / 2), title.str(), text_px, kText, false);

    double bar_m = 0.05;
    const double room_px = std::max(40.0, std::min(map_w_px / 3, 240.0));
    for (double candidate : {0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0}) {
      if (candidate * s_ <= room_px) bar_m = candidate;
    }
    const double y = m + map_h_px + m / 2;
    const double x1 = m + bar_m * s_;
    canvas_.Line({Vec(m, y), Vec(x1, y)}, kText, 3.0, false);
    canvas_.Line({Vec(m, y - 5), Vec(m, y + 5)}, kText, 1.0, false);
    canvas_.Line({Vec(x1, y - 5), Vec(x1, y + 5)}, kText, 1.0, false);
    std::ostringstream label;
    label << bar_m << " m";
    canvas_.Text(Vec(x1 + 8, y), label.str(), text_px * 0.8, kText, false);
  }

  const Map& map_;
  const RenderOptions& o_;
  Canvas& canvas_;
  double s_;  // px per m
};

void WriteFile(const std::string& path, const std::string& what, const char* data,
               std::size_t size) {
  errno = 0;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (out) out.write(data, static_cast<std::streamsize>(size));
  if (out) out.close();
  if (!out) {
    const std::string reason = errno != 0 ? std::strerror(errno) : "write failed";
    throw InputError("cannot write the " + what + " \"" + path + "\": " + reason);
  }
}

}  // namespace

void RenderOptions::Validate() const {
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(pixels_per_tile) && pixels_per_tile >= 8 && pixels_per_tile <= 1000,
      "pixels_per_tile must be in [8, 1000], got " << pixels_per_tile);
  AUTODRIVE_THROW_UNLESS(margin_px >= 0 && margin_px <= 500,
                         "margin_px must be in [0, 500], got " << margin_px);
}

Eigen::Vector2i ImageSizePx(const Map& map, const RenderOptions& options) {
  options.Validate();
  const double w = 2.0 * options.margin_px + std::round(map.cols * options.pixels_per_tile);
  const double h = 2.0 * options.margin_px + std::round(map.rows * options.pixels_per_tile);
  AUTODRIVE_THROW_UNLESS(w <= kMaxSidePx && h <= kMaxSidePx,
                         "the picture of map \"" << map.name << "\" would be " << w << " x " << h
                                                 << " px, more than " << kMaxSidePx
                                                 << " px a side; lower pixels_per_tile ("
                                                 << options.pixels_per_tile << ")");
  return {static_cast<int>(w), static_cast<int>(h)};
}

Eigen::Vector2d MapToPixel(const Map& map, const RenderOptions& options,
                           const Eigen::Vector2d& p_M) {
  const double s = options.pixels_per_tile / map.tile_size_m;
  return {options.margin_px + p_M.x() * s, options.margin_px + (map.size_m().y() - p_M.y()) * s};
}

void RenderPng(const Map& map, const std::string& path, const RenderOptions& options) {
  const Eigen::Vector2i size = ImageSizePx(map, options);
  CvCanvas canvas(size.x(), size.y(), options.ground_only ? kGround : kBackground,
                  options.antialias);
  Scene(map, options, canvas).Draw();
  std::vector<std::uint8_t> png;
  AUTODRIVE_CHECK(cv::imencode(".png", canvas.image(), png), "PNG encoding failed");
  WriteFile(path, "PNG picture", reinterpret_cast<const char*>(png.data()), png.size());
}

Picture RenderPicture(const Map& map, const RenderOptions& options) {
  const Eigen::Vector2i size = ImageSizePx(map, options);
  CvCanvas canvas(size.x(), size.y(), options.ground_only ? kGround : kBackground,
                  options.antialias);
  Scene(map, options, canvas).Draw();
  Picture picture{size.x(), size.y(), {}};
  picture.rgb.resize(static_cast<std::size_t>(size.x()) * static_cast<std::size_t>(size.y()) * 3);
  cv::Mat rgb(size.y(), size.x(), CV_8UC3, picture.rgb.data());
  cv::cvtColor(canvas.image(), rgb, cv::COLOR_BGR2RGB);
  return picture;
}

void RenderSvg(const Map& map, const std::string& path, const RenderOptions& options) {
  const Eigen::Vector2i size = ImageSizePx(map, options);
  SvgCanvas canvas(size.x(), size.y(), map.name);
  Scene(map, options, canvas).Draw();
  const std::string svg = canvas.Xml();
  WriteFile(path, "SVG picture", svg.data(), svg.size());
}

}  // namespace autodrive::maps
