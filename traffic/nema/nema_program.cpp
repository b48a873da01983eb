#include "traffic/nema/nema_program.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <map>
#include <sstream>

#include <pugixml.hpp>

#include "common/error.h"

namespace autodrive::traffic::nema {

namespace {

std::string Join(const std::vector<std::uint32_t>& numbers) {
  std::string out;
  for (std::uint32_t n : numbers) out += (out.empty() ? "" : ",") + std::to_string(n);
  return out;
}

std::string GroupName(const scm::IntersectionModel& x, std::size_t g) {
  return fmt::format("group {} ({})", x.groups[g].id.value(), x.groups[g].name);
}

// SUMO's four places of a ring for a one-ring sequence of 2 to 4 phases: two each side of the
// middle barrier.
std::vector<std::uint32_t> FourPlaces(const std::vector<std::uint32_t>& sequence) {
  switch (sequence.size()) {
    case 2:
      return {sequence[0], 0, sequence[1], 0};
    case 3:
      return {sequence[0], sequence[1], sequence[2], 0};
    default:
      return sequence;
  }
}

}  // namespace

const NemaPhase* NemaProgram::Find(std::uint32_t number) const {
  const auto it = std::ranges::find(phases, number, &NemaPhase::number);
  return it == phases.end() ? nullptr : &*it;
}

std::string SumoSeconds(Duration d) {
  const auto ms = std::chrono::round<std::chrono::milliseconds>(d).count();
  std::string out = fmt::format("{}.{:03}", ms / 1000, std::abs(ms % 1000));
  if (ms < 0 && ms > -1000) out = "-" + out;
  while (out.back() == '0') out.pop_back();
  if (out.back() == '.') out.pop_back();
  return out;
}

NemaProgram NemaProgramOf(const maps::Intersection& map_x, const scm::IntersectionModel& x,
                          const scm::RingPlan& plan) {
  const std::string where = fmt::format("intersection {}", x.name);
  AUTODRIVE_THROW_UNLESS(!plan.phases.empty(),
                         where << ": the plan has no phases (flash or dark): nothing for SUMO's "
                                  "NEMA controller to run");
  AUTODRIVE_THROW_UNLESS(plan.rings.size() == 1,
                         where << ": the plan has " << plan.rings.size()
                               << " rings; only one-ring plans are exported (ring 2 repeats "
                                  "ring 1; SUMO's barriers for two rings are not derived yet)");
  const std::vector<std::uint32_t>& sequence = plan.rings.front();
  AUTODRIVE_THROW_UNLESS(sequence.size() >= 2 && sequence.size() <= 4,
                         where << ": ring 1 has " << sequence.size()
                               << " phases; SUMO's NEMA controller runs 2 to 4 phases a ring (two "
                                  "each side of its barriers)");

  // Link i of the junction's traffic light is movement i of the intersection.
  std::map<MovementId, std::size_t> link_of;
  for (std::size_t i = 0; i < map_x.movements.size(); ++i) link_of[map_x.movements[i]] = i;

  NemaProgram out;
  out.tls = map_x.name;
  out.links = map_x.movements.size();
  std::map<std::size_t, std::uint32_t> phase_of_group;
  for (std::uint32_t number : sequence) {
    const scm::RingPhase* p = plan.Find(number);
    AUTODRIVE_CHECK(p != nullptr, "phase " << number << " of ring 1 is not in the plan");
    const std::string phase = fmt::format("{}: phase {}", where, number);
    AUTODRIVE_THROW_UNLESS(number >= 1 && number <= 8,
                           phase << ": SUMO's NEMA controller numbers its phases 1 to 8");
    AUTODRIVE_THROW_UNLESS(p->recall != scm::Recall::kPed && p->recall != scm::Recall::kSoft,
                           phase << " has " << scm::ToString(p->recall)
                                 << " recall, which SUMO's NEMA controller does not have (only "
                                    "min and max recall)");
    AUTODRIVE_THROW_UNLESS(p->walk == Duration{0} && p->ped_clear == Duration{0},
                           phase << " has a walk or pedestrian clearance time; SUMO's NEMA "
                                    "controller has no pedestrian timing");
    AUTODRIVE_THROW_UNLESS(p->red_revert == Duration{0},
                           phase << " has a red revert time; SUMO's NEMA controller has none");
    AUTODRIVE_THROW_UNLESS(p->yellow > Duration{0},
                           phase << " has no yellow (its groups stay green into the next "
                                    "phase); SUMO's NEMA controller ends every phase with one");
    AUTODRIVE_THROW_UNLESS(!p->groups.empty(), phase << " drives no signal group");
    NemaPhase n;
    n.number = number;
    n.min_green = p->min_green;
    n.max_green = p->max1;
    n.passage = p->passage;
    n.yellow = p->yellow;
    n.red_clear = p->red_clear;
    n.groups = p->groups;
    n.state.assign(out.links, 'r');
    for (std::size_t g : p->groups) {
      AUTODRIVE_CHECK(g < x.groups.size(), "group index " << g);
      const auto [it, fresh] = phase_of_group.emplace(g, number);
      AUTODRIVE_THROW_UNLESS(fresh, where << ": " << GroupName(x, g) << " is driven by phases "
                                          << it->second << " and " << number
                                          << "; a NEMA phase is a light state of its own, so "
                                             "SUMO's controller cannot keep a group green from "
                                             "one phase into the next");
      for (MovementId m : x.groups[g].movements) {
        const auto link = link_of.find(m);
        AUTODRIVE_THROW_UNLESS(link != link_of.end(),
                               where << ": " << GroupName(x, g) << "'s movement " << m.value()
                                     << " is not a movement of map intersection " << map_x.name);
        n.state[link->second] = 'G';
        n.links.push_back(link->second);
      }
    }
    std::ranges::sort(n.links);
    if (p->recall == scm::Recall::kMin) out.min_recall.push_back(number);
    if (p->recall == scm::Recall::kMax) out.max_recall.push_back(number);
    if (!p->non_lock) out.latching.push_back(number);
    out.cycle += n.max_green + n.yellow + n.red_clear;
    out.phases.push_back(std::move(n));
  }
  std::ranges::sort(out.phases, {}, &NemaPhase::number);

  out.rings[0] = FourPlaces(sequence);
  out.rings[1] = out.rings[0];
  const std::vector<std::uint32_t>& r = out.rings[0];
  const std::uint32_t middle = r[1] != 0 ? r[1] : r[0];
  const std::uint32_t last = r[3] != 0 ? r[3] : r[2];
  out.coordinate_phases = {middle, middle};
  out.barrier_phases = {last, last};

  const bool fixed = plan.cycle > Duration{0};
  out.coordinated = fixed;
  out.fix_force_off = fixed;
  if (fixed) {
    AUTODRIVE_CHECK(out.cycle == plan.cycle, "the ring's timings sum to "
                                                 << ToSeconds(out.cycle)
                                                 << " s, the plan's cycle is "
                                                 << ToSeconds(plan.cycle) << " s");
    // SUMO (TS2) starts the coordinated phase's green at the offset; the plan's phase 1 green
    // starts at the plan's offset, and the coordinated phase's that much later.
    Duration start{0};
    for (std::uint32_t number : sequence) {
      if (number == middle) break;
      const NemaPhase& n = *out.Find(number);
      start += n.max_green + n.yellow + n.red_clear;
    }
    out.plan_offset = plan.offset % plan.cycle;
    out.offset = (plan.offset + start) % plan.cycle;
  }
  return out;
}

PlanRef FindPlan(const scm::City& city, const std::string& intersection, const std::string& plan) {
  const scm::IntersectionModel* x = city.Find(intersection);
  if (x == nullptr) {
    std::string names;
    for (const scm::IntersectionModel& m : city.intersections) {
      names += (names.empty() ? "" : ", ") + m.name;
    }
    throw InputError(fmt::format("city {} has no signalised intersection \"{}\" (it has: {})",
                                 city.config.name, intersection, names));
  }
  const std::optional<std::size_t> k = x->PlanIndex(plan);
  if (!k) {
    std::string names;
    for (const scm::Plan& p : x->plans) names += (names.empty() ? "" : ", ") + p.name;
    throw InputError(
        fmt::format("intersection {} has no plan \"{}\" (it has: {})", x->name, plan, names));
  }
  return {x, *k};
}

NemaProgram NemaProgramOf(const scm::City& city, const PlanRef& ref) {
  const scm::IntersectionModel& x = *ref.model;
  const scm::Plan& plan = x.plans[ref.plan];
  try {
    return NemaProgramOf(city.map.intersection(x.id), x, scm::RingPlanOf(x, plan));
  } catch (const InputError& e) {
    throw InputError(
        fmt::format("plan {} ({}): {}", plan.name, scm::ToString(plan.type), e.what()));
  }
}

std::string NemaAdditionalXml(const NemaProgram& program, const NemaOutputs& outputs) {
  pugi::xml_document doc;
  auto decl = doc.append_child(pugi::node_declaration);
  decl.append_attribute("version") = "1.0";
  decl.append_attribute("encoding") = "UTF-8";
  doc.append_child(pugi::node_comment)
      .set_value(fmt::format(" SUMO NEMA program of a city plan (autodrive-scm-nema export); "
                             "link i = movement i of intersection {}. ",
                             program.tls)
                     .c_str());
  auto root = doc.append_child("additional");
  auto tl = root.append_child("tlLogic");
  tl.append_attribute("id") = program.tls.c_str();
  tl.append_attribute("programID") = program.program_id.c_str();
  tl.append_attribute("type") = "NEMA";
  tl.append_attribute("offset") = SumoSeconds(program.offset).c_str();
  const auto param = [&](const char* key, const std::string& value) {
    auto p = tl.append_child("param");
    p.append_attribute("key") = key;
    p.append_attribute("value") = value.c_str();
  };
  param("ring1", Join(program.rings[0]));
  param("ring2", Join(program.rings[1]));
  param("barrierPhases", Join({program.barrier_phases[0], program.barrier_phases[1]}));
  param("coordinatePhases", Join({program.coordinate_phases[0], program.coordinate_phases[1]}));
  param("minRecall", Join(program.min_recall));
  param("maxRecall", Join(program.max_recall));
  param("latchingDetectors", Join(program.latching));
  param("fixForceOff", program.fix_force_off ? "true" : "false");
  param("coordinate-mode", program.coordinated ? "true" : "false");
  param("controllerType", "TS2");
  param("total-cycle-length", SumoSeconds(program.cycle));
  for (const NemaPhase& p : program.phases) {
    auto ph = tl.append_child("phase");
    ph.append_attribute("duration") = "99";  // SUMO's NEMA controller ignores it
    ph.append_attribute("minDur") = SumoSeconds(p.min_green).c_str();
    ph.append_attribute("maxDur") = SumoSeconds(p.max_green).c_str();
    ph.append_attribute("vehext") = SumoSeconds(p.passage).c_str();
    ph.append_attribute("yellow") = SumoSeconds(p.yellow).c_str();
    ph.append_attribute("red") = SumoSeconds(p.red_clear).c_str();
    ph.append_attribute("name") = std::to_string(p.number).c_str();
    ph.append_attribute("state") = p.state.c_str();
  }
  const auto event = [&](const char* type, const std::filesystem::path& dest) {
    if (dest.empty()) return;
    auto e = root.append_child("timedEvent");
    e.append_attribute("type") = type;
    e.append_attribute("source") = program.tls.c_str();
    e.append_attribute("dest") = dest.c_str();
  };
  event("SaveTLSSwitchTimes", outputs.switch_times);
  event("SaveTLSStates", outputs.states);
  std::ostringstream text;
  doc.save(text, "    ");
  std::string out = text.str();
  if (!out.empty() && out.back() != '\n') out += '\n';
  return out;
}

}  // namespace autodrive::traffic::nema
