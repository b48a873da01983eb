#include "maps/sumo.h"

#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <string_view>

#include "common/error.h"
#include "common/process.h"
#include "maps/internal/xml.h"

namespace autodrive::maps {
namespace {

using Vec = Eigen::Vector2d;
namespace fs = std::filesystem;

// ---- Geometry of the grid (the builder's conventions, see map.h) ----------------------------

Vec EdgeMid(const Map& map, TileIndex t, Side s) {
  const Vec centre = map.TileCentre(t);
  return centre + Outward(s) * (map.tile_size_m / 2);
}

TileIndex Neighbour(TileIndex t, Side s) {
  const Vec o = Outward(s);
  return {t.row - static_cast<int>(o.y()), t.col + static_cast<int>(o.x())};
}

bool OnMap(const Map& map, TileIndex t) {
  return t.row >= 0 && t.col >= 0 && t.row < map.rows && t.col < map.cols;
}

// The name of the tile edge on side s of tile t: "n_r1c0_E", named by the tile to the west or
// north of it when that one is on the map.
std::string TileEdgeName(const Map& map, TileIndex t, Side s) {
  if (s == Side::kWest || s == Side::kNorth) {
    const TileIndex n = Neighbour(t, s);
    if (OnMap(map, n)) return "n_" + n.Name() + "_" + SideLetter(Opposite(s));
  }
  return "n_" + t.Name() + "_" + SideLetter(s);
}

// A polyline moved sideways by `offset_m` (positive: to the right of its direction).
Polyline OffsetRight(const Polyline& p, double offset_m) {
  if (offset_m == 0.0 || p.size() < 2) return p;
  Polyline out;
  out.reserve(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec& a = p[i == 0 ? 0 : i - 1];
    const Vec& b = p[i + 1 < p.size() ? i + 1 : i];
    const Vec dir = b - a;
    const Vec t = dir.normalized();
    out.push_back(p[i] + RightOf(t) * offset_m);
  }
  return out;
}

double Length(const Polyline& p) {
  double l = 0;
  for (std::size_t i = 1; i < p.size(); ++i) l += (p[i] - p[i - 1]).norm();
  return l;
}

// The polyline resampled at equal steps along its length of at least `min_step` (lab metres)
// keeping both ends. netconvert drops shape points closer than 0.1 m (SUMO's POSITION_EPS) to
// the previous one, which would cut corners and move ends; see `ShapeStep`.
Polyline Resample(const Polyline& p, double min_step) {
  const double total = Length(p);
  const auto n = static_cast<std::size_t>(std::max(1.0, std::floor(total / min_step)));
  Polyline out = {p.front()};
  std::size_t i = 1;
  double run = 0;  // length of p up to p[i - 1]
  for (std::size_t k = 1; k < n; ++k) {
    const double at = total * static_cast<double>(k) / static_cast<double>(n);
    while (i + 1 < p.size() && run + (p[i] - p[i - 1]).norm() < at) {
      run += (p[i] - p[i - 1]).norm();
      ++i;
    }
    const double seg = (p[i] - p[i - 1]).norm();
    const double f = seg > 0 ? std::clamp((at - run) / seg, 0.0, 1.0) : 0.0;
    out.push_back(p[i - 1] + (p[i] - p[i - 1]) * f);
  }
  out.push_back(p.back());
  return out;
}

// ---- Text -----------------------------------------------------------------------------------

std::string Num(double v) {
  std::string s = fmt::format("{:.6f}", v);
  // Trim trailing zeros ("0.250000" -> "0.25", "2.000000" -> "2").
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  if (s == "-0") s = "0";
  return s;
}

// The polyline in SUMO's coordinates: the map's times `scale`.
std::string Shape(const Polyline& p, double scale) {
  std::string out;
  for (const Vec& v : p) {
    if (!out.empty()) out += ' ';
    out += Num(v.x() * scale) + "," + Num(v.y() * scale);
  }
  return out;
}

// SUMO's rule for ids in networks (SUMOXMLDefinitions::isValidNetID).
bool IsValidSumoId(std::string_view id) {
  return !id.empty() && id.front() != ':' &&
         id.find_first_of(" \t\n\r|\\'\";,<>&") == std::string_view::npos;
}

std::string FileStem(const std::string& name) {
  std::string out;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_' || c == '.';
    out += ok ? c : '_';
  }
  if (out.empty() || out.find_first_not_of('.') == std::string::npos) return "map";
  return out;
}

void WriteFile(const fs::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  AUTODRIVE_THROW_UNLESS(f.good(), "cannot write SUMO file " << path.string());
  f << text;
  f.close();
  AUTODRIVE_THROW_UNLESS(f.good(), "cannot write SUMO file " << path.string());
}

std::string Quote(const std::vector<std::string>& argv) {
  std::string out;
  for (const auto& a : argv) {
    if (!out.empty()) out += ' ';
    const bool plain = !a.empty() && a.find_first_of(" \t\n'\"\\$`*?;&|<>()") == std::string::npos;
    if (plain) {
      out += a;
    } else {
      out += '\'';
      for (char c : a) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
      out += '\'';
    }
  }
  return out;
}

// The program's path: `name` itself when it has a '/', else the first executable `name` in
// PATH; nullopt when there is none.
std::optional<std::string> FindProgram(const std::string& name) {
  const auto executable = [](const std::string& p) {
    struct stat st {};
    return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(p.c_str(), X_OK) == 0;
  };
  if (name.find('/') != std::string::npos) {
    return executable(name) ? std::optional<std::string>(name) : std::nullopt;
  }
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string candidate = (dir.empty() ? std::string(".") : dir) + "/" + name;
    if (executable(candidate)) return candidate;
  }
  return std::nullopt;
}

// ---- The exporter ---------------------------------------------------------------------------

struct EdgeInfo {
  std::string id;
  TileIndex tile;
  Side from = Side::kEast;
  Side to = Side::kEast;
  std::vector<LaneId> lanes;  // by index from the centreline
  std::string from_node;
  std::string to_node;
  Polyline shape;                     // resampled
  std::vector<Polyline> lane_shapes;  // by SUMO index, resampled; empty for one-lane edges
};

struct NodeInfo {
  std::string id;
  Vec position = Vec::Zero();
  Polyline shape;
  std::string type;
  std::string tl;  // traffic light id, for traffic_light nodes
};

class Exporter {
 public:
  Exporter(const Map& map, const SumoOptions& options) : map_(map), o_(options) {}

  // The shortest step between shape points, in lab metres: 0.115 SUMO metres (above SUMO's
  // POSITION_EPS, 0.1 m), but no finer than 1 cm of the lab (the map's own sampling).
  [[nodiscard]] double ShapeStep() const { return std::max(0.115 / o_.scale, 0.01); }
  [[nodiscard]] Polyline Resample(const Polyline& p) const {
    return maps::Resample(p, ShapeStep());
  }
  [[nodiscard]] std::string Shape(const Polyline& p) const { return maps::Shape(p, o_.scale); }
  // A length, speed or acceleration of the lab in SUMO's frame.
  [[nodiscard]] std::string Scaled(double lab) const { return Num(lab * o_.scale); }

  SumoExport Run(const fs::path& dir) {
    o_.Validate();
    MakeJunctions();
    MakeEdges();
    const std::string stem = FileStem(map_.name);
    out_.node_file = dir / (stem + ".nod.xml");
    out_.edge_file = dir / (stem + ".edg.xml");
    out_.connection_file = dir / (stem + ".con.xml");
    out_.tll_file = dir / (stem + ".tll.xml");
    out_.net_file = dir / (stem + ".net.xml");
    out_.vtype_file = dir / (stem + ".vtypes.xml");
    out_.log_file = dir / (stem + ".netconvert.log");
    out_.config_file = dir / (stem + ".sumocfg");
    out_.vehicle_type = o_.vehicle_type.id;
    out_.scale = o_.scale;
    WriteFile(out_.node_file, NodesXml());
    WriteFile(out_.edge_file, EdgesXml());
    WriteFile(out_.connection_file, ConnectionsXml());
    WriteFile(out_.tll_file, TrafficLightsXml());
    WriteFile(out_.vtype_file, VehicleTypeXml());
    RunNetconvert();
    WriteFile(out_.config_file, ConfigXml());
    return std::move(out_);
  }

 private:
  // Intersections become junctions with the intersection's name.
  void MakeJunctions() {
    std::set<std::string> seen;
    for (const Intersection& x : map_.intersections) {
      AUTODRIVE_THROW_UNLESS(IsValidSumoId(x.name),
                             "intersection " << x.tile.Name() << " is named \"" << x.name
                                             << "\", which is not a valid SUMO id (it must not "
                                                "start with ':' nor contain spaces or any of "
                                                "|\\'\";,<>&)");
      AUTODRIVE_THROW_UNLESS(seen.insert(x.name).second, "two intersections are named \""
                                                             << x.name << "\" (tile "
                                                             << x.tile.Name()
                                                             << "); SUMO junction ids must be "
                                                                "unique");
      NodeInfo n;
      n.id = x.name;
      n.position = x.centre;
      switch (x.control) {
        case Control::kSignal:
          n.type = "traffic_light";
          n.tl = x.name;
          break;
        case Control::kStop:
          // A traffic light too: SUMO's allway_stop lets a left turn with a waiting point inside
          // the junction roll through without stopping, and vehicles on the crossing paths of
          // these small boxes collide (see "Traffic lights" above).
          n.type = "traffic_light";
          n.tl = x.name;
          break;
        case Control::kYield:
        case Control::kUncontrolled:
          n.type = "right_before_left";
          break;
      }
      // The mouths of the arms, counter-clockwise, joined by straight corners.
      for (Side s : {Side::kEast, Side::kNorth, Side::kWest, Side::kSouth}) {
        const auto a = std::find_if(x.approaches.begin(), x.approaches.end(),
                                    [s](const Approach& ap) { return ap.side == s; });
        if (a == x.approaches.end()) continue;
        const double h = static_cast<double>(a->ingress.size()) * map_.lane_width_m;
        const Vec mid = EdgeMid(map_, x.tile, s);
        const Vec along = LeftOf(Outward(s)) * h;
        n.shape.push_back(mid - along);
        n.shape.push_back(mid + along);
      }
      junction_of_.emplace(x.id, n.id);
      out_.junctions.emplace(x.id, n.id);
      AddNode(std::move(n));
    }
  }

  // Only an intersection's name can clash with a tile edge's or a loop's junction id.
  void CheckNotAnIntersectionName(const std::string& id) const {
    AUTODRIVE_THROW_UNLESS(std::none_of(out_.junctions.begin(), out_.junctions.end(),
                                        [&](const auto& j) { return j.second == id; }),
                           "an intersection is named \""
                               << id
                               << "\", which is the SUMO junction id of a tile edge or turning "
                                  "loop; rename it");
  }

  void AddNode(NodeInfo n) {
    AUTODRIVE_CHECK(node_index_.count(n.id) == 0, "duplicate SUMO junction " << n.id);
    node_index_.emplace(n.id, nodes_.size());
    nodes_.push_back(std::move(n));
  }

  // The plain junction on side s of tile t, where roads of `lanes_n` lanes per direction
  // cross it.
  std::string PlainNode(TileIndex t, Side s, std::size_t lanes_n) {
    const std::string id = TileEdgeName(map_, t, s);
    CheckNotAnIntersectionName(id);
    if (node_index_.count(id) != 0) return id;
    const Vec mid = EdgeMid(map_, t, s);
    const Vec along = LeftOf(Outward(s)) * (static_cast<double>(lanes_n) * map_.lane_width_m);
    NodeInfo n;
    n.id = id;
    n.type = "priority";
    n.position = mid;
    n.shape = {Vec(mid - along), Vec(mid + along)};
    AddNode(std::move(n));
    return id;
  }

  void MakeEdges() {
    // The road pieces: one per tile and direction, its lanes by index from the centreline.
    std::vector<EdgeInfo> pieces;
    std::map<std::string, std::size_t> index;
    for (const Lane& lane : map_.lanes) {
      const Side from = lane.from_side;
      const Side to = lane.to_side;
      const std::string id =
          lane.tile.Name() + "_" + SideLetter(from) + "_" + std::string(1, SideLetter(to));
      auto [it, inserted] = index.emplace(id, pieces.size());
      if (inserted) {
        EdgeInfo e;
        e.id = id;
        e.tile = lane.tile;
        e.from = from;
        e.to = to;
        pieces.push_back(e);
      }
      EdgeInfo& e = pieces[it->second];
      const auto k = static_cast<std::size_t>(lane.index_from_centre);
      if (e.lanes.size() <= k) e.lanes.resize(k + 1, LaneId(0));
      e.lanes[k] = lane.id;
    }
    for (EdgeInfo& e : pieces) {
      for (LaneId l : e.lanes) AUTODRIVE_CHECK(l.value() != 0, "edge " << e.id << " misses a lane");
      const Lane& inner = map_.lane(e.lanes.front());
      const std::size_t n = e.lanes.size();
      e.from_node =
          inner.egress_of ? junction_of_.at(*inner.egress_of) : PlainNode(e.tile, e.from, n);
      e.to_node =
          inner.ingress_of ? junction_of_.at(*inner.ingress_of) : PlainNode(e.tile, e.to, n);
      // The middle of the edge's lanes: lane 0 (next to the centreline) moved to the right.
      // SUMO would place the lanes of a coarse shape by its end segments' normals, so edges of
      // several lanes give each lane its own (resampled) shape too.
      e.shape = OffsetRight(inner.centreline, static_cast<double>(n - 1) / 2 * map_.lane_width_m);
      if (e.from != e.to) {
        e.shape = Resample(e.shape);
        if (n > 1) {
          for (std::size_t i = 0; i < n; ++i) {
            e.lane_shapes.push_back(Resample(map_.lane(e.lanes[n - 1 - i]).centreline));
          }
        }
        AddEdge(std::move(e));
        continue;
      }
      // A turning loop leaves and enters one junction; SUMO ignores such self-looped edges, so
      // it is split at half its length by a plain junction.
      AUTODRIVE_CHECK(n == 1, "turning loop " << e.id << " with " << n << " lanes");
      auto [first, second] = SplitAtHalfLength(e.shape);
      const Vec p = second.front();
      const Vec t = (second[1] - second[0]).normalized();
      NodeInfo apex;
      apex.id = "n_" + e.tile.Name() + "_loop";
      CheckNotAnIntersectionName(apex.id);
      apex.type = "priority";
      apex.position = p;
      apex.shape = {Vec(p + LeftOf(t) * map_.lane_width_m / 2),
                    Vec(p + RightOf(t) * map_.lane_width_m / 2)};
      EdgeInfo a = e, b = e;
      a.id = e.id + "_a";
      a.to_node = apex.id;
      a.shape = Resample(first);
      b.id = e.id + "_b";
      b.from_node = apex.id;
      b.shape = Resample(second);
      AddNode(std::move(apex));
      AddEdge(std::move(a));
      AddEdge(std::move(b));
    }
    for (const Movement& m : map_.movements) {
      SumoMovement sm;
      sm.from = out_.lane_pieces.at(m.from).back();
      sm.to = out_.lane_pieces.at(m.to).front();
      const Intersection& x = map_.intersection(m.intersection);
      sm.junction = junction_of_.at(x.id);
      if (x.control == Control::kSignal || x.control == Control::kStop) {
        const auto pos = std::find(x.movements.begin(), x.movements.end(), m.id);
        AUTODRIVE_CHECK(pos != x.movements.end(),
                        "movement " << m.name << " not in its intersection");
        sm.tls_link_index = static_cast<int>(pos - x.movements.begin());
      }
      out_.movements.emplace(m.id, sm);
    }
  }

  // The polyline cut in two at half its length (the cut point ends one and starts the other).
  static std::pair<Polyline, Polyline> SplitAtHalfLength(const Polyline& p) {
    AUTODRIVE_CHECK(p.size() >= 2);
    const double total = Length(p);
    double run = 0;
    for (std::size_t i = 1; i < p.size(); ++i) {
      const double seg = (p[i] - p[i - 1]).norm();
      if (run + seg >= total / 2 && seg > 0) {
        const double f = (total / 2 - run) / seg;
        const Vec cut = p[i - 1] + (p[i] - p[i - 1]) * f;
        Polyline first(p.begin(), p.begin() + static_cast<std::ptrdiff_t>(i));
        Polyline second(p.begin() + static_cast<std::ptrdiff_t>(i), p.end());
        if ((cut - first.back()).norm() > 1e-9) first.push_back(cut);
        if ((second.front() - cut).norm() > 1e-9) second.insert(second.begin(), cut);
        if (first.size() < 2) first.insert(first.begin(), p.front());
        return {first, second};
      }
      run += seg;
    }
    AUTODRIVE_CHECK(false, "cannot split a polyline of length " << total);
    return {};
  }

  void AddEdge(EdgeInfo e) {
    AUTODRIVE_CHECK(e.from_node != e.to_node, "self-looped SUMO edge " << e.id);
    const int n = static_cast<int>(e.lanes.size());
    for (int k = 0; k < n; ++k) {
      const LaneId l = e.lanes[static_cast<std::size_t>(k)];
      const SumoLaneRef ref{e.id, n - 1 - k};
      out_.lanes.emplace(l, ref);  // the first piece stays
      out_.lane_pieces[l].push_back(ref);
    }
    out_.edges.emplace(e.id, e.lanes);
    edges_.push_back(std::move(e));
  }

  // The plain XML files, built as pugixml documents (every value escaped by pugixml) and
  // written with four spaces of indentation per level.
  static constexpr const char* kIndent = "    ";

  std::string NodesXml() const {
    pugi::xml_document doc;
    internal::AddXmlDeclaration(doc);
    internal::AppendComment(doc, " written by autodrive::maps::ExportSumo ");
    pugi::xml_node root = internal::AppendElement(doc, "nodes");
    for (const NodeInfo& n : nodes_) {
      pugi::xml_node node = internal::AppendElement(root, "node",
                                                    {{"id", n.id},
                                                     {"x", Scaled(n.position.x())},
                                                     {"y", Scaled(n.position.y())},
                                                     {"type", n.type}});
      if (!n.tl.empty()) internal::AppendAttribute(node, "tl", n.tl);
      internal::AppendAttribute(node, "shape", Shape(n.shape));
    }
    return internal::XmlText(doc, kIndent);
  }

  std::string EdgesXml() const {
    pugi::xml_document doc;
    internal::AddXmlDeclaration(doc);
    pugi::xml_node root = internal::AppendElement(doc, "edges");
    for (const EdgeInfo& e : edges_) {
      pugi::xml_node edge = internal::AppendElement(root, "edge",
                                                    {{"id", e.id},
                                                     {"from", e.from_node},
                                                     {"to", e.to_node},
                                                     {"numLanes", std::to_string(e.lanes.size())},
                                                     {"speed", Scaled(o_.speed_mps)},
                                                     {"width", Scaled(map_.lane_width_m)},
                                                     {"spreadType", "center"},
                                                     {"shape", Shape(e.shape)}});
      for (std::size_t i = 0; i < e.lane_shapes.size(); ++i) {
        internal::AppendElement(edge, "lane",
                                {{"index", std::to_string(i)}, {"shape", Shape(e.lane_shapes[i])}});
      }
    }
    return internal::XmlText(doc, kIndent);
  }

  // `<connection from=.. to=.. fromLane=.. toLane=..>` appended to `parent`.
  static pugi::xml_node AppendConnection(pugi::xml_node parent, const SumoLaneRef& from,
                                         const SumoLaneRef& to) {
    return internal::AppendElement(parent, "connection",
                                   {{"from", from.edge},
                                    {"to", to.edge},
                                    {"fromLane", std::to_string(from.index)},
                                    {"toLane", std::to_string(to.index)}});
  }

  std::string ConnectionsXml() const {
    pugi::xml_document doc;
    internal::AddXmlDeclaration(doc);
    pugi::xml_node root = internal::AppendElement(doc, "connections");
    // Across plain junctions: each lane to its successors, and a turning loop's halves.
    for (const Lane& lane : map_.lanes) {
      const auto& pieces = out_.lane_pieces.at(lane.id);
      for (std::size_t i = 0; i < pieces.size(); ++i) {
        std::vector<SumoLaneRef> next;
        if (i + 1 < pieces.size()) {
          next.push_back(pieces[i + 1]);
        } else {
          for (LaneId l : lane.successors) next.push_back(out_.lane_pieces.at(l).front());
        }
        for (const SumoLaneRef& to : next) {
          internal::AppendAttribute(AppendConnection(root, pieces[i], to), "length",
                                    Num(kPlainConnectionLength_m));
        }
      }
    }
    // The movements, each after a comment with its name.
    for (const Movement& m : map_.movements) {
      const SumoMovement& sm = out_.movements.at(m.id);
      internal::AppendComment(root, " " + m.name + " ");
      internal::AppendAttribute(AppendConnection(root, sm.from, sm.to), "shape",
                                Shape(Resample(m.path)));
    }
    return internal::XmlText(doc, kIndent);
  }

  std::string TrafficLightsXml() const {
    for (const auto& [id, program] : o_.programs) {
      const auto it = std::ranges::find(map_.intersections, id, &Intersection::id);
      if (it == map_.intersections.end() || it->control != Control::kSignal) {
        throw InputError("a SUMO program is given for intersection " + std::to_string(id.value()) +
                         ", which is not a signalised intersection of map " + map_.name);
      }
    }
    pugi::xml_document doc;
    internal::AddXmlDeclaration(doc);
    pugi::xml_node root = internal::AppendElement(doc, "tlLogics");
    for (const Intersection& x : map_.intersections) {
      if (x.control != Control::kSignal && x.control != Control::kStop) continue;
      const bool stop = x.control == Control::kStop;
      const std::string& id = junction_of_.at(x.id);
      const auto given = stop ? o_.programs.end() : o_.programs.find(x.id);
      const Duration offset = given == o_.programs.end() ? Duration{0} : given->second.offset;
      pugi::xml_node logic = internal::AppendElement(
          root, "tlLogic",
          {{"id", id}, {"type", "static"}, {"programID", "0"}, {"offset", Num(ToSeconds(offset))}});
      const auto phase = [&](Duration d, const std::string& state, const std::string& name) {
        internal::AppendElement(
            logic, "phase", {{"duration", Num(ToSeconds(d))}, {"state", state}, {"name", name}});
      };
      if (given != o_.programs.end()) {
        // The given program: each phase's movements green, then those the next phase does not
        // keep yellow, then all red.
        const auto& phases = given->second.phases;
        if (phases.empty()) throw InputError("the SUMO program of " + x.name + " has no phase");
        for (const SumoSignalPhase& ph : phases) {
          for (MovementId mid : ph.movements) {
            if (std::ranges::find(x.movements, mid) == x.movements.end()) {
              throw InputError("the SUMO program of " + x.name + " names movement " +
                               std::to_string(mid.value()) + ", not one of its own");
            }
          }
          if (ph.green <= Duration::zero()) {
            throw InputError("the SUMO program of " + x.name + " has a phase without green");
          }
        }
        for (std::size_t k = 0; k < phases.size(); ++k) {
          const auto& next = phases[(k + 1) % phases.size()].movements;
          std::string green, yellow, red;
          for (MovementId mid : x.movements) {
            const bool on =
                std::ranges::find(phases[k].movements, mid) != phases[k].movements.end();
            const bool kept = on && std::ranges::find(next, mid) != next.end();
            green += on ? 'G' : 'r';
            yellow += kept ? 'G' : (on ? 'y' : 'r');
            red += kept ? 'G' : 'r';
          }
          const std::string name = "phase " + std::to_string(k + 1);
          phase(phases[k].green, green, name + " green");
          if (phases[k].yellow > Duration::zero())
            phase(phases[k].yellow, yellow, name + " yellow");
          if (phases[k].all_red > Duration::zero())
            phase(phases[k].all_red, red, name + " all red");
        }
      }
      for (const Approach& a :
           given != o_.programs.end() ? std::vector<Approach>{} : x.approaches) {
        std::string green, yellow;
        for (MovementId mid : x.movements) {
          const bool served = map_.movement(mid).from_approach == a.id;
          green += served ? 'G' : 'r';
          yellow += served ? 'y' : 'r';
        }
        const std::string side(1, SideLetter(a.side));
        phase(stop ? o_.stop_green : o_.green, green, side + " green");
        phase(stop ? o_.stop_yellow : o_.yellow, yellow, side + " yellow");
        const Duration all_red = stop ? o_.stop_all_red : o_.all_red;
        if (all_red > Duration::zero()) {
          phase(all_red, std::string(x.movements.size(), 'r'), side + " all red");
        }
      }
      for (std::size_t i = 0; i < x.movements.size(); ++i) {
        const SumoMovement& sm = out_.movements.at(x.movements[i]);
        pugi::xml_node connection = AppendConnection(root, sm.from, sm.to);
        internal::AppendAttribute(connection, "tl", id);
        internal::AppendAttribute(connection, "linkIndex", std::to_string(i));
      }
    }
    return internal::XmlText(doc, kIndent);
  }

  std::string VehicleTypeXml() const {
    pugi::xml_document doc;
    internal::AddXmlDeclaration(doc);
    internal::AppendComment(
        doc, " written by autodrive::maps::ExportSumo: lab sizes x " + Num(o_.scale) + " ");
    pugi::xml_node root = internal::AppendElement(doc, "additional");
    std::vector<const SumoVehicleType*> types = {&o_.vehicle_type};
    for (const SumoVehicleType& v : o_.other_vehicle_types) types.push_back(&v);
    for (const SumoVehicleType* t : types) {
      const SumoVehicleType& v = *t;
      internal::AppendElement(root, "vType",
                              {{"id", v.id},
                               {"vClass", v.vclass},
                               {"guiShape", v.gui_shape},
                               {"color", v.color},
                               {"length", Scaled(v.length_m)},
                               {"width", Scaled(v.width_m)},
                               {"height", Scaled(v.height_m)},
                               {"maxSpeed", Scaled(v.max_speed_mps)},
                               {"accel", Scaled(v.accel_mps2)},
                               {"decel", Scaled(v.decel_mps2)},
                               {"emergencyDecel", Scaled(v.emergency_decel_mps2)},
                               {"apparentDecel", Scaled(v.decel_mps2)},
                               {"minGap", Scaled(v.min_gap_m)},
                               {"speedFactor", Num(v.speed_factor)},
                               {"speedDev", "0"},
                               {"sigma", Num(v.sigma)}});
    }
    return internal::XmlText(doc, kIndent);
  }

  // The SUMO configuration: the network, the vehicle types, and the options under which a lab's
  // traffic runs: a vehicle is never teleported (nothing vanishes unplanned; a jam shows), and
  // collisions are checked inside junctions too and reported, not resolved by removing cars.
  std::string ConfigXml() const {
    pugi::xml_document doc;
    internal::AddXmlDeclaration(doc);
    internal::AppendComment(doc, " written by autodrive::maps::ExportSumo; run: sumo -c " +
                                     out_.config_file.filename().string() + " -r ROUTES.rou.xml ");
    pugi::xml_node root = internal::AppendElement(doc, "configuration");
    pugi::xml_node input = internal::AppendElement(root, "input");
    internal::AppendElement(input, "net-file", {{"value", out_.net_file.filename().string()}});
    internal::AppendElement(input, "additional-files",
                            {{"value", out_.vtype_file.filename().string()}});
    pugi::xml_node processing = internal::AppendElement(root, "processing");
    internal::AppendElement(processing, "time-to-teleport", {{"value", "-1"}});
    internal::AppendElement(processing, "collision.check-junctions", {{"value", "true"}});
    internal::AppendElement(processing, "collision.action", {{"value", "warn"}});
    internal::AppendElement(root, "time").append_child("step-length").append_attribute("value") =
        "0.05";
    return internal::XmlText(doc, kIndent);
  }

  void RunNetconvert() {
    const std::optional<std::string> program = FindProgram(o_.netconvert);
    std::vector<std::string> args = {o_.netconvert,
                                     "--node-files",
                                     out_.node_file.string(),
                                     "--edge-files",
                                     out_.edge_file.string(),
                                     "--connection-files",
                                     out_.connection_file.string(),
                                     "--tllogic-files",
                                     out_.tll_file.string(),
                                     "--output-file",
                                     out_.net_file.string(),
                                     "--no-internal-links",
                                     "false",
                                     "--no-turnarounds",
                                     "true",
                                     "--offset.disable-normalization",
                                     "true",
                                     "--roundabouts.guess",
                                     "false",
                                     "--default.lanewidth",
                                     Scaled(map_.lane_width_m),
                                     "--default.speed",
                                     Scaled(o_.speed_mps),
                                     "--geometry.min-radius",
                                     Scaled(0.05),
                                     "--precision",
                                     "4",
                                     "--xml-validation",
                                     "never"};
    args.insert(args.end(), o_.extra_netconvert_args.begin(), o_.extra_netconvert_args.end());
    out_.netconvert_command = args;
    const std::string command = Quote(args);
    AUTODRIVE_THROW_UNLESS(program.has_value(), "cannot run netconvert: \""
                                                    << o_.netconvert
                                                    << "\" is not an executable file nor on PATH "
                                                       "(install SUMO's netconvert); command: "
                                                    << command);
    // Through sh only to send netconvert's stderr to the pipe we read.
    std::vector<std::string> argv = {"/bin/sh", "-c", "exec \"$0\" \"$@\" 2>&1", *program};
    argv.insert(argv.end(), args.begin() + 1, args.end());
    std::string output;
    int code = -1;
    {
      ChildProcess child(argv);
      child.CloseStdin();
      while (auto line = child.ReadLine(std::chrono::minutes(2))) output += *line + "\n";
      const std::optional<int> rc = child.Wait(std::chrono::seconds(10));
      code = rc ? *rc : child.Stop();
      if (!rc) output += "(netconvert did not finish; stopped)\n";
    }
    WriteFile(out_.log_file, output);
    AUTODRIVE_THROW_UNLESS(code == 0 && fs::exists(out_.net_file),
                           "netconvert failed (exit code " << code << ") on map \"" << map_.name
                                                           << "\"; command: " << command
                                                           << "\nits output:\n"
                                                           << output);
  }

  const Map& map_;
  const SumoOptions& o_;
  SumoExport out_;
  std::vector<NodeInfo> nodes_;
  std::map<std::string, std::size_t> node_index_;
  std::vector<EdgeInfo> edges_;
  std::map<IntersectionId, std::string> junction_of_;
};

}  // namespace

void SumoOptions::Validate() const {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  AUTODRIVE_THROW_UNLESS(positive(speed_mps),
                         "SumoOptions.speed_mps must be > 0, got " << speed_mps);
  AUTODRIVE_THROW_UNLESS(!netconvert.empty(), "SumoOptions.netconvert must not be empty");
  AUTODRIVE_THROW_UNLESS(
      stop_green > Duration::zero() && stop_yellow >= Duration::zero() &&
          stop_all_red >= Duration::zero(),
      "SumoOptions.stop_green must be > 0 s and stop_yellow, stop_all_red >= 0 s");
  AUTODRIVE_THROW_UNLESS(green > Duration::zero(),
                         "SumoOptions.green must be > 0 s, got " << ToSeconds(green) << " s");
  AUTODRIVE_THROW_UNLESS(yellow >= Duration::zero(),
                         "SumoOptions.yellow must be >= 0 s, got " << ToSeconds(yellow) << " s");
  AUTODRIVE_THROW_UNLESS(all_red >= Duration::zero(),
                         "SumoOptions.all_red must be >= 0 s, got " << ToSeconds(all_red) << " s");
  AUTODRIVE_THROW_UNLESS(positive(scale), "SumoOptions.scale must be > 0, got " << scale);
  std::set<std::string> ids = {vehicle_type.id};
  for (const SumoVehicleType& t : other_vehicle_types) {
    AUTODRIVE_THROW_UNLESS(ids.insert(t.id).second,
                           "SumoOptions: two vehicle types have the id \"" << t.id << "\"");
  }
  vehicle_type.Validate();
  for (const SumoVehicleType& t : other_vehicle_types) t.Validate();
}

void SumoVehicleType::Validate() const {
  const SumoVehicleType& v = *this;
  const auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  AUTODRIVE_THROW_UNLESS(
      IsValidSumoId(v.id) && IsValidSumoId(v.vclass),
      "vehicle type id \"" << v.id << "\" or class \"" << v.vclass << "\" is not a valid SUMO id");
  const std::pair<const char*, double> dims[] = {
      {"length_m", v.length_m},        {"width_m", v.width_m},
      {"height_m", v.height_m},        {"max_speed_mps", v.max_speed_mps},
      {"accel_mps2", v.accel_mps2},    {"decel_mps2", v.decel_mps2},
      {"speed_factor", v.speed_factor}};
  for (const auto& [key, value] : dims) {
    AUTODRIVE_THROW_UNLESS(positive(value),
                           "vehicle type " << v.id << ": " << key << " must be > 0, got " << value);
  }
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(v.min_gap_m) && v.min_gap_m >= 0,
      "vehicle type " << v.id << ": min_gap_m must be >= 0, got " << v.min_gap_m);
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(v.emergency_decel_mps2) && v.emergency_decel_mps2 >= v.decel_mps2,
      "vehicle type " << v.id << ": emergency_decel_mps2 must be >= decel_mps2 (" << v.decel_mps2
                      << "), got " << v.emergency_decel_mps2);
  AUTODRIVE_THROW_UNLESS(v.sigma >= 0 && v.sigma <= 1,
                         "vehicle type " << v.id << ": sigma must be in [0, 1], got " << v.sigma);
}

SumoVehicleType LabBus() {
  SumoVehicleType t;
  t.id = "bus";
  t.vclass = "bus";
  t.gui_shape = "bus";
  t.length_m = 0.857;
  t.width_m = 0.182;
  t.height_m = 0.3;
  t.max_speed_mps = 0.2;
  t.accel_mps2 = 0.3;
  t.decel_mps2 = 0.8;
  t.emergency_decel_mps2 = 1.6;
  t.color = "1,0.8,0";
  return t;
}

SumoVehicleType LabEmergencyVehicle() {
  SumoVehicleType t;
  t.id = "emergency";
  t.vclass = "emergency";
  t.gui_shape = "emergency";
  t.color = "1,0,0";
  return t;
}

SumoExport ExportSumo(const Map& map, const std::string& out_dir, const SumoOptions& options) {
  AUTODRIVE_THROW_UNLESS(!out_dir.empty(), "ExportSumo needs an output directory");
  AUTODRIVE_THROW_UNLESS(!map.lanes.empty(), "map \""
                                                 << map.name
                                                 << "\" has no lanes: there is no road network "
                                                    "for SUMO (open floors are not exported)");
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  AUTODRIVE_THROW_UNLESS(
      !ec && fs::is_directory(out_dir),
      "cannot create the SUMO output directory \"" << out_dir << "\": " << ec.message());
  return Exporter(map, options).Run(fs::path(out_dir));
}

}  // namespace autodrive::maps
