#include "maps/layout.h"

#include <cctype>
#include <charconv>
#include <sstream>

#include "common/config.h"
#include "common/error.h"

namespace autodrive::maps {
namespace {

struct TypeName {
  ModuleType type;
  std::string_view name;
};
constexpr TypeName kTypeNames[] = {
    {ModuleType::kEmpty, "empty"},     {ModuleType::kStraight, "straight"},
    {ModuleType::kCurve, "curve"},     {ModuleType::kIntersection, "x4"},
    {ModuleType::kTJunction, "t"},     {ModuleType::kRoadEnd, "end"},
    {ModuleType::kParking, "parking"}, {ModuleType::kRamp, "ramp"},
    {ModuleType::kOpen, "open"},
};

struct ControlName {
  Control control;
  std::string_view name;
};
constexpr ControlName kControlNames[] = {{Control::kSignal, "signal"},
                                         {Control::kStop, "stop"},
                                         {Control::kYield, "yield"},
                                         {Control::kUncontrolled, "none"}};

template <typename T>
T ParseNumber(std::string_view text, std::string_view what, std::string_view cell) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  AUTODRIVE_THROW_UNLESS(
      ec == std::errc() && end == text.data() + text.size(),
      what << " must be a number, got \"" << text << "\" in cell \"" << cell << "\"");
  return value;
}

// The shortest text that reads back as exactly `v`.
std::string FormatNumber(double v) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  AUTODRIVE_CHECK(ec == std::errc());
  return std::string(buffer, end);
}

}  // namespace

std::string_view ToString(ModuleType type) {
  for (const auto& [t, name] : kTypeNames) {
    if (t == type) return name;
  }
  AUTODRIVE_CHECK(false, "unknown ModuleType " << static_cast<int>(type));
}

std::string_view ToString(Control control) {
  for (const auto& [c, name] : kControlNames) {
    if (c == control) return name;
  }
  AUTODRIVE_CHECK(false, "unknown Control " << static_cast<int>(control));
}

namespace {

// A head id: a whole number in [1, 999999] (it names the head's topics, signal_<id>).
std::uint32_t ParseHeadId(std::string_view value, std::string_view text) {
  const int id = ParseNumber<int>(value, "a head id", text);
  AUTODRIVE_THROW_UNLESS(id >= 1 && id <= 999999, "a head id must be in [1, 999999], got "
                                                      << id << " in cell \"" << text << "\"");
  return static_cast<std::uint32_t>(id);
}

// heads=FIRST or heads=E4/N5/W6/S7 (no commas or colons: the cell is a plain scalar in a YAML
// flow sequence).
void ParseHeads(std::string_view value, std::string_view text, Cell& cell) {
  AUTODRIVE_THROW_UNLESS(!cell.first_head && cell.head_by_side.empty(),
                         "heads is given twice in cell \"" << text << "\"");
  if (!value.empty() && std::isdigit(static_cast<unsigned char>(value[0])) != 0) {
    cell.first_head = ParseHeadId(value, text);
    return;
  }
  std::size_t begin = 0;
  while (begin <= value.size()) {
    const std::size_t end = std::min(value.find('/', begin), value.size());
    const std::string_view item = value.substr(begin, end - begin);
    AUTODRIVE_THROW_UNLESS(
        item.size() >= 2 && std::string_view("ENWS").find(item[0]) != std::string_view::npos,
        "heads wants a first id (heads=4) or SIDE and id per approach with SIDE one of E, N, W, "
        "S (heads=E4/N5/W6/S7), got \""
            << item << "\" in cell \"" << text << "\"");
    const std::uint32_t id = ParseHeadId(item.substr(1), text);
    AUTODRIVE_THROW_UNLESS(cell.head_by_side.emplace(item[0], id).second,
                           "heads gives side " << item[0] << " twice in cell \"" << text << "\"");
    begin = end + 1;
  }
}

}  // namespace

Cell Cell::FromConfigString(std::string_view text) {
  std::istringstream words{std::string(text)};
  std::string head;
  words >> head;
  AUTODRIVE_THROW_UNLESS(!head.empty(), "empty cell (write \"empty\" or \".\")");
  Cell cell;
  std::string_view type_text = head;
  if (const auto at = head.find('@'); at != std::string::npos) {
    type_text = std::string_view(head).substr(0, at);
    const std::string_view rot = std::string_view(head).substr(at + 1);
    cell.rotation_deg = ParseNumber<int>(rot, "the rotation", text);
    AUTODRIVE_THROW_UNLESS(cell.rotation_deg == 0 || cell.rotation_deg == 90 ||
                               cell.rotation_deg == 180 || cell.rotation_deg == 270,
                           "the rotation must be 0, 90, 180 or 270 degrees, got "
                               << cell.rotation_deg << " in cell \"" << text << "\"");
  }
  if (type_text == ".") type_text = "empty";
  bool known = false;
  for (const auto& [t, name] : kTypeNames) {
    if (name == type_text) {
      cell.type = t;
      known = true;
    }
  }
  if (!known) {
    throw InputError("unknown module \"" + std::string(type_text) +
                     "\" (known: empty, straight, curve, x4, t, end, parking, ramp, open)");
  }
  std::string option;
  while (words >> option) {
    const auto eq = option.find('=');
    AUTODRIVE_THROW_UNLESS(
        eq != std::string::npos && eq > 0,
        "expected key=value after the module, got \"" << option << "\" in cell \"" << text << "\"");
    const std::string key = option.substr(0, eq);
    const std::string value = option.substr(eq + 1);
    if (key == "lanes") {
      cell.lanes = ParseNumber<int>(value, "lanes", text);
      AUTODRIVE_THROW_UNLESS(*cell.lanes == 1 || *cell.lanes == 2,
                             "lanes must be 1 or 2 per direction, got " << *cell.lanes);
    } else if (key == "width") {
      cell.lane_width_m = ParseNumber<double>(value, "width", text);
      AUTODRIVE_THROW_UNLESS(
          *cell.lane_width_m >= 0.1 && *cell.lane_width_m <= 2.0,
          "width must be a lane width in [0.1, 2] m, got " << *cell.lane_width_m);
    } else if (key == "control") {
      bool found = false;
      for (const auto& [c, name] : kControlNames) {
        if (name == value) {
          cell.control = c;
          found = true;
        }
      }
      AUTODRIVE_THROW_UNLESS(
          found, "control must be signal, stop, yield or none, got \"" << value << "\"");
      AUTODRIVE_THROW_UNLESS(
          cell.type == ModuleType::kIntersection || cell.type == ModuleType::kTJunction,
          "control applies to intersections (x4, t), not to " << ToString(cell.type));
    } else if (key == "rise") {
      cell.rise_m = ParseNumber<double>(value, "rise", text);
      AUTODRIVE_THROW_UNLESS(cell.type == ModuleType::kRamp, "rise applies to ramps only");
      AUTODRIVE_THROW_UNLESS(std::abs(cell.rise_m) <= 0.5,
                             "a ramp rises at most 0.5 m, got " << cell.rise_m);
    } else if (key == "elevation") {
      cell.elevation_m = ParseNumber<double>(value, "elevation", text);
    } else if (key == "name") {
      AUTODRIVE_THROW_UNLESS(!value.empty(), "name must not be empty");
      cell.name = value;
    } else if (key == "heads") {
      ParseHeads(value, text, cell);
    } else {
      throw InputError("unknown cell option \"" + key +
                       "\" (known: lanes, width, control, rise, elevation, name, heads)");
    }
  }
  AUTODRIVE_THROW_UNLESS(
      (!cell.first_head && cell.head_by_side.empty()) ||
          ((cell.type == ModuleType::kIntersection || cell.type == ModuleType::kTJunction) &&
           cell.control == Control::kSignal),
      "heads applies to signalised intersections (x4, t with control=signal) only, in cell \""
          << text << "\"");
  return cell;
}

std::string Cell::ToConfigString() const {
  std::string s(ToString(type));
  if (rotation_deg != 0) s += "@" + std::to_string(rotation_deg);
  if (lanes) s += " lanes=" + std::to_string(*lanes);
  if (lane_width_m) s += " width=" + FormatNumber(*lane_width_m);
  if ((type == ModuleType::kIntersection || type == ModuleType::kTJunction) &&
      control != Control::kSignal) {
    s += " control=" + std::string(ToString(control));
  }
  if (rise_m != 0.0) s += " rise=" + FormatNumber(rise_m);
  if (elevation_m != 0.0) s += " elevation=" + FormatNumber(elevation_m);
  if (!name.empty()) s += " name=" + name;
  if (first_head) s += " heads=" + std::to_string(*first_head);
  if (!head_by_side.empty()) {
    s += " heads=";
    bool first = true;
    for (const char side : {'E', 'N', 'W', 'S'}) {
      if (const auto it = head_by_side.find(side); it != head_by_side.end()) {
        s += (first ? "" : "/") + std::string(1, side) + std::to_string(it->second);
        first = false;
      }
    }
  }
  return s;
}

void Layout::Validate() const {
  AUTODRIVE_THROW_UNLESS(!name.empty(), "name must not be empty");
  AUTODRIVE_THROW_UNLESS(!grid.empty() && !grid.front().empty(),
                         "grid must have at least one row and one column");
  for (std::size_t r = 0; r < grid.size(); ++r) {
    AUTODRIVE_THROW_UNLESS(grid[r].size() == grid.front().size(),
                           "grid row " << r << " has " << grid[r].size() << " cells but row 0 has "
                                       << grid.front().size() << " (the grid must be rectangular)");
  }
  // The road (2 * lanes * lane width) must fit in a tile with a margin of 5% each side.
  for (std::size_t r = 0; r < grid.size(); ++r) {
    for (std::size_t c = 0; c < grid[r].size(); ++c) {
      const int lanes = grid[r][c].lanes.value_or(lanes_per_direction);
      const double road_m = 2.0 * lanes * grid[r][c].lane_width_m.value_or(lane_width_m);
      AUTODRIVE_THROW_UNLESS(road_m <= 0.9 * tile_size_m,
                             "tile r" << r << "c" << c << ": a road of " << lanes
                                      << " lane(s) per direction is " << road_m
                                      << " m wide and does not fit a " << tile_size_m
                                      << " m tile (at most 90% of it)");
    }
  }
}

Layout MakeLayout(const std::string& name, const std::vector<std::vector<std::string>>& rows) {
  Layout l;
  l.name = name;
  for (const auto& row : rows) {
    std::vector<Cell> cells;
    for (const auto& text : row) cells.push_back(Cell::FromConfigString(text));
    l.grid.push_back(std::move(cells));
  }
  return l;
}

Layout LoadLayout(const std::string& path) { return config::LoadFile<Layout>(path); }

}  // namespace autodrive::maps
