#include "traffic/standalone.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>

#include <pugixml.hpp>

#include "traffic/network.h"

#include "common/error.h"
#include "scm/core/city.h"

namespace autodrive::traffic {

namespace {

std::string Join(const std::vector<std::string>& v) {
  std::string out;
  for (const std::string& s : v) out += (out.empty() ? "" : " ") + s;
  return out;
}

void Save(const pugi::xml_document& doc, const std::filesystem::path& path) {
  AUTODRIVE_THROW_UNLESS(doc.save_file(path.c_str(), "    "), "cannot write " << path.string());
}

}  // namespace

std::map<IntersectionId, maps::SumoSignalProgram> PlanPrograms(const scm::City& city,
                                                               const std::string& plan) {
  std::map<IntersectionId, maps::SumoSignalProgram> programs;
  for (const scm::IntersectionModel& x : city.intersections) {
    const std::optional<std::size_t> k = x.PlanIndex(plan);
    if (!k) throw InputError(x.name + " has no plan \"" + plan + "\"");
    const scm::Plan& p = x.plans[*k];
    if (p.type != scm::PlanType::kFixed) {
      throw InputError(x.name + "'s plan " + plan + " is " + std::string(scm::ToString(p.type)) +
                       ", not fixed-time");
    }
    maps::SumoSignalProgram& program = programs[x.id];
    program.offset = p.offset;
    for (std::size_t i = 0; i < p.phases.size(); ++i) {
      const scm::Phase& phase = p.phases[i];
      const scm::Phase& next = p.phases[(i + 1) % p.phases.size()];
      maps::SumoSignalPhase out;
      out.green = phase.green;
      for (std::size_t g : phase.groups) {
        const scm::SignalGroup& group = x.groups[g];
        out.movements.insert(out.movements.end(), group.movements.begin(), group.movements.end());
        if (std::ranges::find(next.groups, g) == next.groups.end()) {
          out.yellow = std::max(out.yellow, group.timing.yellow);
          out.all_red = std::max(out.all_red, group.timing.red_clearance);
        }
      }
      program.phases.push_back(std::move(out));
    }
  }
  return programs;
}

StandaloneFiles ExportStandalone(const scm::City& city, const TrafficConfig& config,
                                 const std::filesystem::path& dir, Duration duration,
                                 const std::string& plan) {
  std::filesystem::create_directories(dir);
  const TrafficNetwork network(city.map, dir / "network", config.speed_mps,
                               plan.empty() ? std::map<IntersectionId, maps::SumoSignalProgram>{}
                                            : PlanPrograms(city, plan));
  std::mt19937_64 rng(config.seed);
  // Edges enough to drive for the whole duration at the speed limit on the shortest edge.
  double shortest = std::numeric_limits<double>::infinity();
  for (const std::string& e : network.edges()) shortest = std::min(shortest, network.EdgeLength(e));
  const auto walk = static_cast<std::size_t>(std::ceil(ToSeconds(duration) * config.speed_mps /
                                                       std::max(shortest, 0.05))) +
                    4;

  struct Trip {
    double depart = 0;
    std::string id, type, depart_pos;
    std::vector<std::string> edges;
  };
  std::vector<Trip> trips;
  double total = 0;
  for (const TypeShare& t : config.mix) total += t.weight;
  const auto type = [&]() -> const std::string& {
    double r = std::uniform_real_distribution<double>(0.0, std::max(total, 1e-12))(rng);
    for (const TypeShare& t : config.mix) {
      if (r < t.weight) return t.type;
      r -= t.weight;
    }
    return config.mix.back().type;
  };
  // Lengths of the export's own types; another type (of a route file) is taken as a Nigel's.
  const maps::SumoOptions types;
  const auto length_of = [&](const std::string& id) {
    for (const maps::SumoVehicleType& t : types.other_vehicle_types) {
      if (t.id == id) return t.length_m * network.scale();
    }
    return types.vehicle_type.length_m * network.scale();
  };
  const std::vector<Placement> placed =
      network.PlaceVehicles(config.vehicles, walk, 0.05 * network.scale(), rng, type, length_of);
  for (std::size_t k = 0; k < placed.size(); ++k) {
    Trip t;
    t.id = "bg_" + std::to_string(k);
    t.edges = placed[k].route;
    t.type = placed[k].type;
    t.depart_pos = fmt::format("{:.3f}", placed[k].pos);
    trips.push_back(std::move(t));
  }
  for (std::size_t i = 0; i < config.flows.size(); ++i) {
    const FlowConfig& f = config.flows[i];
    const std::string& from = network.EdgeOfLane(f.from);
    const double period = 3600.0 / f.per_hour;
    for (int n = 0; f.count == 0 || n < f.count; ++n) {
      const double depart = ToSeconds(f.begin_s) + n * period;
      if (depart > ToSeconds(duration)) break;
      Trip t;
      t.depart = depart;
      t.id = fmt::format("flow{}_{}", i, n);
      t.type = f.type;
      t.depart_pos = "base";
      if (f.to.empty()) {
        t.edges = {from};
        for (std::string& e : network.RandomWalk(from, walk, rng)) t.edges.push_back(std::move(e));
      } else {
        t.edges = network.Route(from, network.EdgeOfLane(f.to));
        AUTODRIVE_THROW_UNLESS(!t.edges.empty(),
                               "traffic.flows: no route from " << f.from << " to " << f.to);
      }
      trips.push_back(std::move(t));
    }
  }
  std::stable_sort(trips.begin(), trips.end(),
                   [](const Trip& a, const Trip& b) { return a.depart < b.depart; });

  StandaloneFiles out;
  const std::string stem = network.files().net_file.stem().string();
  out.net_file = network.files().net_file;
  out.route_file = dir / (stem + ".rou.xml");
  out.config_file = dir / (stem + ".sumocfg");
  out.vehicles = static_cast<int>(trips.size());
  {
    pugi::xml_document doc;
    auto root = doc.append_child("routes");
    for (const Trip& t : trips) {
      auto v = root.append_child("vehicle");
      v.append_attribute("id") = t.id.c_str();
      v.append_attribute("type") = t.type.c_str();
      v.append_attribute("depart") = fmt::format("{:.2f}", t.depart).c_str();
      v.append_attribute("departLane") = "best";
      v.append_attribute("departPos") = t.depart_pos.c_str();
      v.append_child("route").append_attribute("edges") = Join(t.edges).c_str();
    }
    Save(doc, out.route_file);
  }
  {
    // The export's configuration (no teleports, junction collision checks), with the routes.
    pugi::xml_document doc;
    AUTODRIVE_THROW_UNLESS(doc.load_file(network.files().config_file.c_str()),
                           "cannot read " << network.files().config_file.string());
    pugi::xml_node input = doc.child("configuration").child("input");
    const auto relative = [&](const std::filesystem::path& p) {
      return std::filesystem::relative(p, dir).string();
    };
    input.child("net-file").attribute("value") = relative(network.files().net_file).c_str();
    input.child("additional-files").attribute("value") =
        relative(network.files().vtype_file).c_str();
    std::string routes = out.route_file.filename().string();
    for (const std::string& f : config.route_files) routes += "," + f;
    input.append_child("route-files").append_attribute("value") = routes.c_str();
    doc.child("configuration").child("time").append_child("end").append_attribute("value") =
        fmt::format("{:.2f}", ToSeconds(duration)).c_str();
    Save(doc, out.config_file);
  }
  return out;
}

}  // namespace autodrive::traffic
