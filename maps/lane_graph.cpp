#include "maps/lane_graph.h"

#include <algorithm>
#include <deque>
#include <functional>
#include <limits>
#include <queue>

namespace autodrive::maps {
namespace {

bool OnBoundary(const Map& map, const Eigen::Vector2d& p) {
  const Eigen::Vector2d size = map.size_m();
  constexpr double kEps = 1e-6;
  return std::abs(p.x()) < kEps || std::abs(p.y()) < kEps || std::abs(p.x() - size.x()) < kEps ||
         std::abs(p.y() - size.y()) < kEps;
}

std::size_t Index(LaneId id) { return id.value() - 1; }

}  // namespace

std::vector<LaneId> NextLanes(const Map& map, LaneId lane) {
  const Lane& l = map.lane(lane);
  std::vector<LaneId> next = l.successors;
  for (MovementId m : l.movements_out) next.push_back(map.movement(m).to);
  return next;
}

bool LeavesMap(const Map& map, const Lane& lane) {
  return lane.successors.empty() && lane.movements_out.empty() &&
         OnBoundary(map, lane.centreline.back());
}

bool EntersMap(const Map& map, const Lane& lane) {
  return lane.predecessors.empty() && lane.movements_in.empty() &&
         OnBoundary(map, lane.centreline.front());
}

std::vector<std::string> CheckReachability(const Map& map) {
  const std::size_t n = map.lanes.size();
  std::vector<std::vector<std::size_t>> fwd(n), bwd(n);
  for (const auto& lane : map.lanes) {
    for (LaneId next : NextLanes(map, lane.id)) {
      fwd[Index(lane.id)].push_back(Index(next));
      bwd[Index(next)].push_back(Index(lane.id));
    }
  }
  // Lanes on a cycle: strongly connected components (Tarjan, iterative) of size > 1 or with a
  // self-loop.
  std::vector<int> index(n, -1), low(n, 0), comp(n, -1);
  std::vector<bool> on_stack(n, false);
  std::vector<std::size_t> stack;
  int counter = 0, ncomp = 0;
  std::vector<int> comp_size;
  for (std::size_t root = 0; root < n; ++root) {
    if (index[root] >= 0) continue;
    std::vector<std::pair<std::size_t, std::size_t>> work{{root, 0}};
    while (!work.empty()) {
      auto& [v, i] = work.back();
      if (i == 0) {
        index[v] = low[v] = counter++;
        stack.push_back(v);
        on_stack[v] = true;
      }
      if (i < fwd[v].size()) {
        const std::size_t w = fwd[v][i++];
        if (index[w] < 0) {
          work.push_back({w, 0});
        } else if (on_stack[w]) {
          low[v] = std::min(low[v], index[w]);
        }
        continue;
      }
      if (low[v] == index[v]) {
        int size = 0;
        for (;;) {
          const std::size_t w = stack.back();
          stack.pop_back();
          on_stack[w] = false;
          comp[w] = ncomp;
          ++size;
          if (w == v) break;
        }
        comp_size.push_back(size);
        ++ncomp;
      }
      const std::size_t done = v;
      work.pop_back();
      if (!work.empty()) low[work.back().first] = std::min(low[work.back().first], low[done]);
    }
  }
  std::vector<bool> cyclic(n, false);
  for (std::size_t v = 0; v < n; ++v) {
    cyclic[v] = comp_size[static_cast<std::size_t>(comp[v])] > 1 ||
                std::find(fwd[v].begin(), fwd[v].end(), v) != fwd[v].end();
  }
  const auto spread = [&](const std::vector<std::vector<std::size_t>>& edges,
                          const std::function<bool(std::size_t)>& seed) {
    std::vector<bool> seen(n, false);
    std::deque<std::size_t> queue;
    for (std::size_t v = 0; v < n; ++v) {
      if (seed(v)) {
        seen[v] = true;
        queue.push_back(v);
      }
    }
    while (!queue.empty()) {
      const std::size_t v = queue.front();
      queue.pop_front();
      for (std::size_t w : edges[v]) {
        if (!seen[w]) {
          seen[w] = true;
          queue.push_back(w);
        }
      }
    }
    return seen;
  };
  // Can reach an exit or a loop: spread backwards from them. Reachable from an entry or a
  // loop: spread forwards from them.
  const auto can_leave =
      spread(bwd, [&](std::size_t v) { return cyclic[v] || LeavesMap(map, map.lanes[v]); });
  const auto can_be_reached =
      spread(fwd, [&](std::size_t v) { return cyclic[v] || EntersMap(map, map.lanes[v]); });
  std::vector<std::string> problems;
  for (std::size_t v = 0; v < n; ++v) {
    if (!can_leave[v])
      problems.push_back(map.lanes[v].name + " cannot reach the map boundary or a loop");
    if (!can_be_reached[v]) {
      problems.push_back(map.lanes[v].name + " cannot be reached from the map boundary or a loop");
    }
  }
  return problems;
}

std::vector<LaneId> Route(const Map& map, LaneId from, LaneId to) {
  const std::size_t n = map.lanes.size();
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  std::vector<std::size_t> prev(n, n);
  using Item = std::pair<double, std::size_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  dist[Index(from)] = map.lane(from).length_m;
  queue.push({dist[Index(from)], Index(from)});
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > dist[v]) continue;
    if (v == Index(to)) break;
    const Lane& lane = map.lanes[v];
    for (LaneId next : lane.successors) {
      const double nd = d + map.lane(next).length_m;
      if (nd < dist[Index(next)]) {
        dist[Index(next)] = nd;
        prev[Index(next)] = v;
        queue.push({nd, Index(next)});
      }
    }
    for (MovementId m : lane.movements_out) {
      const Movement& mv = map.movement(m);
      const double nd = d + mv.length_m + map.lane(mv.to).length_m;
      if (nd < dist[Index(mv.to)]) {
        dist[Index(mv.to)] = nd;
        prev[Index(mv.to)] = v;
        queue.push({nd, Index(mv.to)});
      }
    }
  }
  if (!std::isfinite(dist[Index(to)])) return {};
  std::vector<LaneId> route;
  for (std::size_t v = Index(to); v != n; v = prev[v]) route.push_back(map.lanes[v].id);
  std::reverse(route.begin(), route.end());
  return route;
}

}  // namespace autodrive::maps
