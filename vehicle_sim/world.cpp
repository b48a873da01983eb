#include "vehicle_sim/world.h"

#include <ode/ode.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <deque>
#include <limits>
#include <mutex>
#include <sstream>
#include <utility>

#include "common/error.h"
#include "maps/map.h"
#include "maps/mesh.h"
#include "vehicle_sim/internal/ode_vehicle.h"

namespace autodrive::vehicle_sim {

std::string_view ToString(Wheel wheel) {
  switch (wheel) {
    case Wheel::kFrontLeft:
      return "front_left";
    case Wheel::kFrontRight:
      return "front_right";
    case Wheel::kRearLeft:
      return "rear_left";
    case Wheel::kRearRight:
      return "rear_right";
  }
  return "?";
}

namespace {

using internal::GeomTag;

// ODE keeps process-wide state: initialise it once; each thread that collides needs its data.
// ODE's messages (its LCP solver's "internal error, s <= 0" on a degenerate contact set, which
// it recovers from) go to the log at debug level instead of stderr; its errors (misuse) are
// fatal as ODE makes them.
void OdeMessage(int num, const char* message, va_list args) {
  char text[512];
  std::vsnprintf(text, sizeof text, message, args);
  spdlog::debug("ODE message {}: {}", num, text);
}

void InitOde() {
  static std::once_flag once;
  std::call_once(once, [] {
    dInitODE2(0);
    dSetMessageHandler(&OdeMessage);
  });
  dAllocateODEDataForThread(dAllocateMaskAll);
}

constexpr int kMaxContacts = 8;  // per pair of geoms
constexpr double kInf = std::numeric_limits<double>::infinity();
// Background traffic is given to ODE only within this distance of a car (between bounding
// circles, m), chosen again when a car has moved half of it: no car reaches a box left out
// before the boxes are chosen again.
constexpr double kTrafficReach = 0.5;
// How far the lab's floor (z = 0) reaches beyond a map with terrain (m).
constexpr double kFloorMargin = 50.0;

}  // namespace

namespace {

// Whether a box's footprint (4 corners) and a car's body box (pose, half extents), seen from
// above, overlap: separating axes of the two rectangles.
bool FootprintsOverlap(const maps::Polyline& box, const Eigen::Isometry3d& X_MB,
                       const Eigen::Vector3d& half) {
  const Eigen::Vector2d c = X_MB.translation().head<2>();
  const Eigen::Vector2d u = X_MB.linear().col(0).head<2>().normalized() * half.x();
  const Eigen::Vector2d v = X_MB.linear().col(1).head<2>().normalized() * half.y();
  const std::array<Eigen::Vector2d, 4> car{c - u - v, c + u - v, c + u + v, c - u + v};
  const auto separated = [](const auto& a, const auto& b, const Eigen::Vector2d& axis) {
    double a_lo = 1e300, a_hi = -1e300, b_lo = 1e300, b_hi = -1e300;
    for (const Eigen::Vector2d& p : a) {
      a_lo = std::min(a_lo, p.dot(axis));
      a_hi = std::max(a_hi, p.dot(axis));
    }
    for (const Eigen::Vector2d& p : b) {
      b_lo = std::min(b_lo, p.dot(axis));
      b_hi = std::max(b_hi, p.dot(axis));
    }
    return a_hi <= b_lo || b_hi <= a_lo;
  };
  for (std::size_t k = 0; k < 4; ++k) {
    for (const auto* poly : {&box, static_cast<const maps::Polyline*>(nullptr)}) {
      const Eigen::Vector2d edge =
          poly != nullptr ? box[(k + 1) % 4] - box[k] : car[(k + 1) % 4] - car[k];
      const Eigen::Vector2d axis(-edge.y(), edge.x());
      if (separated(box, car, axis)) return false;
    }
  }
  return true;
}

}  // namespace

struct World::Impl {
  WorldOptions options;
  double step_s = 0.0;
  dWorldID world = nullptr;
  dSpaceID static_space = nullptr;   // terrain and obstacles: a hash space
  dSpaceID vehicle_space = nullptr;  // chassis and wheels: a simple space (insertion order)
  dJointGroupID contacts = nullptr;
  std::vector<std::unique_ptr<internal::OdeVehicle>> vehicles;
  std::vector<std::unique_ptr<GeomTag>> static_tags;
  GeomTag terrain_tag{GeomTag::Kind::kTerrain, -1, -1, -1};
  GeomTag obstacle_tag{GeomTag::Kind::kObstacle, -1, -1, -1};
  // Terrain mesh (kept alive for ODE), or none on flat ground.
  std::vector<double> terrain_vertices;
  std::vector<dTriIndex> terrain_indices;
  dTriMeshDataID terrain_data = nullptr;
  // Background traffic (`SetTraffic`): every box, and a pool of ODE boxes without a body
  // (fixed, of infinite mass), in a simple space of their own (pairs in insertion order), for
  // the boxes within reach of a car: the first `traffic_enabled` of the pool, the rest
  // disabled.
  dSpaceID traffic_space = nullptr;
  std::vector<DynamicBox> traffic;
  struct TrafficGeom {
    dGeomID geom = nullptr;
    GeomTag tag{GeomTag::Kind::kTraffic, -1, -1, -1};
  };
  std::deque<TrafficGeom> traffic_geoms;  // a deque: ODE holds pointers to the tags
  std::size_t traffic_enabled = 0;
  bool traffic_dirty = false;
  std::vector<Eigen::Vector2d> traffic_chosen_at;  // each car's centre when they were chosen
  std::vector<double> car_radius;                  // scratch: each car's bounding circle
  std::vector<TrafficContact> traffic_contacts;    // of the last step
  StaticGeometry geometry;                         // what is static: the ODE geoms and the scene
  mutable std::optional<StaticScene> scene;        // built from `geometry` on demand
  // Timed boxes (`AddTimedBox`): each with its prism and ODE geom (enabled while it stands).
  std::vector<TimedBox> timed;
  struct Placed {
    Prism prism;
    dGeomID geom = nullptr;
    bool standing = false;
  };
  std::vector<Placed> placed;  // by timed box
  std::int64_t steps = 0;
  std::string failure;  // set when a step went non-finite

  explicit Impl(const WorldOptions& o) : options(o), step_s(ToSeconds(o.step)) {
    AUTODRIVE_THROW_UNLESS(step_s > 0, "the physics step must be positive, got " << step_s << " s");
    InitOde();
    world = dWorldCreate();
    dWorldSetGravity(world, 0, 0, -options.gravity_mps2);
    dWorldSetERP(world, 0.2);
    dWorldSetCFM(world, 1e-9);
    static_space = dHashSpaceCreate(nullptr);
    vehicle_space = dSimpleSpaceCreate(nullptr);
    traffic_space = dSimpleSpaceCreate(nullptr);
    contacts = dJointGroupCreate(0);
  }

  ~Impl() {
    vehicles.clear();
    dJointGroupDestroy(contacts);
    dSpaceDestroy(vehicle_space);
    dSpaceDestroy(traffic_space);  // and its geoms
    dSpaceDestroy(static_space);   // destroys its geoms (cleanup mode on by default)
    if (terrain_data != nullptr) dGeomTriMeshDataDestroy(terrain_data);
    dWorldDestroy(world);
  }

  void Tag(dGeomID g, GeomTag* tag, unsigned long category, unsigned long collide) {
    dGeomSetData(g, tag);
    dGeomSetCategoryBits(g, category);
    dGeomSetCollideBits(g, collide);
  }

  void AddFlatGround() {
    dGeomID plane = dCreatePlane(static_space, 0, 0, 1, 0);
    Tag(plane, &terrain_tag, internal::kTerrainBit, internal::kWheelBit | internal::kChassisBit);
  }

  // A static prism as an ODE box: the simulator takes rectangular footprints (every wall and
  // box maps/ builds, and the unmapped boxes).
  dGeomID AddPrism(const Prism& prism) {
    const maps::Polyline& f = prism.footprint_M;
    AUTODRIVE_THROW_UNLESS(f.size() == 4, "a static obstacle with "
                                              << f.size()
                                              << " corners: the simulator takes rectangles");
    const Eigen::Vector2d along = f[1] - f[0];
    const Eigen::Vector2d across = f[2] - f[1];
    AUTODRIVE_THROW_UNLESS(std::abs(along.dot(across)) <= 1e-6 * along.norm() * across.norm() &&
                               (f[3] - f[0] - across).norm() <= 1e-6,
                           "a static obstacle's footprint is not a rectangle: ("
                               << f[0].transpose() << "), (" << f[1].transpose() << "), ("
                               << f[2].transpose() << "), (" << f[3].transpose() << ")");
    const double height = prism.z_top_m - prism.z_bottom_m;
    AUTODRIVE_THROW_UNLESS(height > 0, "a static obstacle needs a positive height, got " << height);
    const Eigen::Vector2d centre = (f[0] + f[2]) / 2;
    dGeomID box = dCreateBox(static_space, along.norm(), across.norm(), height);
    dGeomSetPosition(box, centre.x(), centre.y(), prism.z_bottom_m + height / 2);
    dMatrix3 R;
    dRFromAxisAndAngle(R, 0, 0, 1, std::atan2(along.y(), along.x()));
    dGeomSetRotation(box, R);
    Tag(box, &obstacle_tag, internal::kObstacleBit, internal::kChassisBit);
    return box;
  }

  // Places and removes the timed boxes for the world's time; the scene is built again when
  // one changed. A box due where a car's body is cannot be put there: that is refused
  // (InputError naming the box, the car and the time), as ODE would otherwise push the car
  // out of a box of infinite mass with unbounded speeds.
  void UpdateTimed() {
    const Duration t = steps * options.step;
    for (std::size_t i = 0; i < timed.size(); ++i) {
      const bool stands = timed[i].StandsAt(t);
      Placed& p = placed[i];
      if (stands == p.standing) continue;
      if (stands) {
        for (std::size_t v = 0; v < vehicles.size(); ++v) {
          Eigen::Isometry3d X_MB;
          Eigen::Vector3d half;
          vehicles[v]->Box(X_MB, half);
          AUTODRIVE_THROW_UNLESS(
              !FootprintsOverlap(p.prism.footprint_M, X_MB, half),
              "an unmapped obstacle due at t = "
                  << ToSeconds(t) << " s at (" << timed[i].box.X_MB.translation().x() << ", "
                  << timed[i].box.X_MB.translation().y() << ") would stand where vehicle " << v
                  << "'s body is: place it where no car is at that time");
        }
      }
      p.standing = stands;
      if (stands) {
        dGeomEnable(p.geom);
      } else {
        dGeomDisable(p.geom);
      }
      scene.reset();
    }
  }

  // The scene's geometry: the permanent one, and the timed boxes standing now.
  StaticGeometry SceneGeometry() const {
    StaticGeometry g = geometry;
    for (const Placed& p : placed) {
      if (p.standing) g.prisms.push_back(p.prism);
    }
    return g;
  }

  void AddCylinder(const Cylinder& c) {
    const double height = c.z_top_m - c.z_bottom_m;
    dGeomID pole = dCreateCylinder(static_space, c.radius_m, height);  // along z
    dGeomSetPosition(pole, c.centre_M.x(), c.centre_M.y(), c.z_bottom_m + height / 2);
    Tag(pole, &obstacle_tag, internal::kObstacleBit, internal::kChassisBit);
  }

  void BuildTerrain(const maps::Map& m) {
    bool flat = true;
    for (double e : m.terrain.tile_elevation_m) flat = flat && e == 0.0;
    for (double r : m.terrain.tile_rise_m) flat = flat && r == 0.0;
    if (flat) {
      AddFlatGround();
      return;
    }
    // Two triangles per tile, heights taken just inside the tile so a ramp's corners are its
    // own (as maps/mesh.cpp writes mesh.obj); steps between tiles are left open.
    const double T = m.tile_size_m;
    const double e = 1e-9;
    for (int r = 0; r < m.rows; ++r) {
      for (int c = 0; c < m.cols; ++c) {
        const double x0 = c * T, x1 = (c + 1) * T;
        const double y0 = (m.rows - 1 - r) * T, y1 = y0 + T;
        const auto base = static_cast<dTriIndex>(terrain_vertices.size() / 3);
        const auto vertex = [&](double x, double y, double xi, double yi) {
          terrain_vertices.insert(terrain_vertices.end(), {x, y, maps::TerrainHeight(m, xi, yi)});
        };
        vertex(x0, y0, x0 + e, y0 + e);
        vertex(x1, y0, x1 - e, y0 + e);
        vertex(x1, y1, x1 - e, y1 - e);
        vertex(x0, y1, x0 + e, y1 - e);
        terrain_indices.insert(terrain_indices.end(),
                               {base, base + 1, base + 2, base, base + 2, base + 3});
      }
    }
    // The lab's floor around the map (z = 0): four strips out to kFloorMargin.
    const double W = m.cols * T;
    const double H = m.rows * T;
    const double F = kFloorMargin;
    const auto floor_quad = [&](double x0, double y0, double x1, double y1) {
      const auto base = static_cast<dTriIndex>(terrain_vertices.size() / 3);
      terrain_vertices.insert(terrain_vertices.end(),
                              {x0, y0, 0.0, x1, y0, 0.0, x1, y1, 0.0, x0, y1, 0.0});
      terrain_indices.insert(terrain_indices.end(),
                             {base, base + 1, base + 2, base, base + 2, base + 3});
    };
    floor_quad(-F, -F, 0, H + F);
    floor_quad(W, -F, W + F, H + F);
    floor_quad(0, -F, W, 0);
    floor_quad(0, H, W, H + F);
    terrain_data = dGeomTriMeshDataCreate();
    dGeomTriMeshDataBuildDouble(terrain_data, terrain_vertices.data(), 3 * sizeof(double),
                                static_cast<int>(terrain_vertices.size() / 3),
                                terrain_indices.data(), static_cast<int>(terrain_indices.size()),
                                3 * sizeof(dTriIndex));
    dGeomID mesh = dCreateTriMesh(static_space, terrain_data, nullptr, nullptr, nullptr);
    Tag(mesh, &terrain_tag, internal::kTerrainBit, internal::kWheelBit | internal::kChassisBit);
  }

  // Gives ODE the traffic boxes within reach of a car, when the boxes changed or a car moved
  // half the reach since they were last chosen.
  void ChooseTraffic() {
    if (traffic.empty() && traffic_enabled == 0) return;
    bool choose = traffic_dirty || traffic_chosen_at.size() != vehicles.size();
    Eigen::Isometry3d X_MB;
    Eigen::Vector3d half;
    for (std::size_t i = 0; i < vehicles.size() && !choose; ++i) {
      vehicles[i]->Box(X_MB, half);
      choose = (X_MB.translation().head<2>() - traffic_chosen_at[i]).norm() > kTrafficReach / 2;
    }
    if (!choose) return;
    traffic_dirty = false;
    traffic_chosen_at.resize(vehicles.size());
    car_radius.resize(vehicles.size());
    // The cars' bounding rectangle, grown by the reach, rejects most of a city's boxes at once.
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(kInf), hi = -lo;
    for (std::size_t i = 0; i < vehicles.size(); ++i) {
      vehicles[i]->Box(X_MB, half);
      traffic_chosen_at[i] = X_MB.translation().head<2>();
      car_radius[i] = half.norm();
      lo = lo.cwiseMin(traffic_chosen_at[i] - Eigen::Vector2d::Constant(car_radius[i]));
      hi = hi.cwiseMax(traffic_chosen_at[i] + Eigen::Vector2d::Constant(car_radius[i]));
    }
    std::size_t used = 0;
    for (std::size_t k = 0; k < traffic.size(); ++k) {
      const DynamicBox& b = traffic[k];
      const Eigen::Vector2d c = b.X_MB.translation().head<2>();
      const double grow = b.half_extents_m.norm() + kTrafficReach;
      if ((c.array() < lo.array() - grow).any() || (c.array() > hi.array() + grow).any()) continue;
      bool near = false;
      for (std::size_t i = 0; i < vehicles.size() && !near; ++i) {
        const double reach = b.half_extents_m.norm() + car_radius[i] + kTrafficReach;
        near = (c - traffic_chosen_at[i]).squaredNorm() <= reach * reach;
      }
      if (!near) continue;
      if (used == traffic_geoms.size()) {
        TrafficGeom& g = traffic_geoms.emplace_back();
        g.geom = dCreateBox(traffic_space, 1, 1, 1);
        Tag(g.geom, &g.tag, internal::kTrafficBit, internal::kChassisBit);
      }
      TrafficGeom& g = traffic_geoms[used++];
      g.tag.traffic = static_cast<int>(k);
      const Eigen::Vector3d lengths = 2 * b.half_extents_m;
      dGeomBoxSetLengths(g.geom, lengths.x(), lengths.y(), lengths.z());
      const Eigen::Vector3d p = b.X_MB.translation();
      dGeomSetPosition(g.geom, p.x(), p.y(), p.z());
      const Eigen::Matrix3d m = b.X_MB.linear();
      dMatrix3 R;
      for (int r = 0; r < 3; ++r) {
        for (int col = 0; col < 3; ++col) R[4 * r + col] = m(r, col);
        R[4 * r + 3] = 0;
      }
      dGeomSetRotation(g.geom, R);
      dGeomEnable(g.geom);
    }
    for (std::size_t k = used; k < traffic_enabled; ++k) dGeomDisable(traffic_geoms[k].geom);
    traffic_enabled = used;
  }

  // The collision callback: tyres for wheel-ground pairs, plain contacts for bodies.
  static void NearCallback(void* data, dGeomID g1, dGeomID g2) {
    auto* self = static_cast<Impl*>(data);
    if (dGeomIsSpace(g1) || dGeomIsSpace(g2)) {
      dSpaceCollide2(g1, g2, data, &NearCallback);
      return;
    }
    // ODE collides two spaces by walking the one with fewer geoms, disabled ones included
    // (dSpaceCollide2): a background box out of reach (disabled where it last stood) would still
    // be hit there.
    if (dGeomIsEnabled(g1) == 0 || dGeomIsEnabled(g2) == 0) return;
    const auto* t1 = static_cast<const GeomTag*>(dGeomGetData(g1));
    const auto* t2 = static_cast<const GeomTag*>(dGeomGetData(g2));
    if (t1 == nullptr || t2 == nullptr) return;
    // Parts of one car do not collide with each other.
    if (t1->vehicle >= 0 && t1->vehicle == t2->vehicle) return;
    dContact contact[kMaxContacts];
    const int n = dCollide(g1, g2, kMaxContacts, &contact[0].geom, sizeof(dContact));
    if (n == 0) return;
    if (t1->kind == GeomTag::Kind::kWheel || t2->kind == GeomTag::Kind::kWheel) {
      const bool first_is_wheel = t1->kind == GeomTag::Kind::kWheel;
      const GeomTag* wheel = first_is_wheel ? t1 : t2;
      // One contact per wheel (the deepest): the tyre's slip coefficients are per wheel.
      int deepest = 0;
      for (int i = 1; i < n; ++i) {
        if (contact[i].geom.depth > contact[deepest].geom.depth) deepest = i;
      }
      dContact& c = contact[deepest];
      if (!first_is_wheel) {  // the joint takes the wheel as body 1: turn the contact round
        for (int k = 0; k < 3; ++k) c.geom.normal[k] = -c.geom.normal[k];
        std::swap(c.geom.g1, c.geom.g2);
      }
      internal::OdeVehicle& v = *self->vehicles[static_cast<std::size_t>(wheel->vehicle)];
      v.FillTyreContact(wheel->wheel, c);
      dJointID j = dJointCreateContact(self->world, self->contacts, &c);
      dJointAttach(j, dGeomGetBody(first_is_wheel ? g1 : g2),
                   dGeomGetBody(first_is_wheel ? g2 : g1));
      v.AttachFeedback(wheel->wheel, j, c.geom.normal);
      return;
    }
    if (t1->kind == GeomTag::Kind::kTraffic || t2->kind == GeomTag::Kind::kTraffic) {
      const bool first_is_traffic = t1->kind == GeomTag::Kind::kTraffic;
      const TrafficContact touch{(first_is_traffic ? t2 : t1)->vehicle,
                                 (first_is_traffic ? t1 : t2)->traffic};
      auto& touches = self->traffic_contacts;
      if (std::find(touches.begin(), touches.end(), touch) == touches.end()) {
        touches.push_back(touch);
      }
    }
    for (int i = 0; i < n; ++i) {
      dContact& c = contact[i];
      c.surface.mode = dContactBounce | dContactApprox1 | dContactSoftERP | dContactSoftCFM;
      c.surface.soft_cfm = 1e-5;  // a little give keeps redundant box contacts well posed
      c.surface.mu = self->options.body_friction;
      c.surface.bounce = self->options.body_bounce;
      c.surface.bounce_vel = 0.05;
      c.surface.soft_erp = 0.5;
      dJointID j = dJointCreateContact(self->world, self->contacts, &c);
      dJointAttach(j, dGeomGetBody(g1), dGeomGetBody(g2));
    }
  }
};

World::World(const WorldOptions& options) : impl_(std::make_unique<Impl>(options)) {
  impl_->AddFlatGround();
}

World::World(const maps::Map& map, const WorldOptions& options)
    : impl_(std::make_unique<Impl>(options)) {
  impl_->geometry = GeometryFromMap(map, options.scene);
  impl_->BuildTerrain(map);
  for (const Prism& p : impl_->geometry.prisms) impl_->AddPrism(p);
  for (const Cylinder& c : impl_->geometry.cylinders) impl_->AddCylinder(c);
}

World::~World() = default;

namespace {
Prism BoxPrism(const TerrainModel& terrain, const StaticBox& box) {
  AUTODRIVE_THROW_UNLESS(box.size_m.allFinite() && box.size_m.minCoeff() > 0,
                         "a static box needs a positive size, got " << box.size_m.transpose());
  const Eigen::Vector2d c = box.X_MB.translation();
  const Eigen::Matrix2d R = box.X_MB.rotation_matrix();
  const Eigen::Vector2d u = R.col(0) * (box.size_m.x() / 2);
  const Eigen::Vector2d v = R.col(1) * (box.size_m.y() / 2);
  return PrismOnGround(terrain, {c - u - v, c + u - v, c + u + v, c - u + v}, box.size_m.z());
}
}  // namespace

void World::AddStaticBox(const StaticBox& box) {
  const Prism prism = BoxPrism(impl_->geometry.terrain, box);
  impl_->AddPrism(prism);
  impl_->geometry.prisms.push_back(prism);
  impl_->scene.reset();
}

void World::AddTimedBox(const TimedBox& box) {
  AUTODRIVE_THROW_UNLESS(!box.until || *box.until > box.from,
                         "a timed box is removed at " << ToSeconds(box.until.value_or(Duration{}))
                                                      << " s, not after it is placed at "
                                                      << ToSeconds(box.from) << " s");
  const Prism prism = BoxPrism(impl_->geometry.terrain, box.box);
  Impl& w = *impl_;
  w.timed.push_back(box);
  w.placed.push_back({prism, w.AddPrism(prism), false});
  dGeomDisable(w.placed.back().geom);
  w.UpdateTimed();
}

std::span<const TimedBox> World::TimedBoxes() const { return impl_->timed; }

void World::SetTraffic(std::span<const DynamicBox> boxes) {
  for (const DynamicBox& b : boxes) {
    const Eigen::Vector3d& half = b.half_extents_m;
    AUTODRIVE_THROW_UNLESS(b.X_MB.matrix().allFinite() && half.allFinite() && half.minCoeff() > 0,
                           "background object " << b.id.value() << ": a pose of "
                                                << b.X_MB.translation().transpose()
                                                << " and half extents of " << half.transpose()
                                                << " m: both must be finite, extents positive");
  }
  impl_->traffic.assign(boxes.begin(), boxes.end());
  impl_->traffic_dirty = true;
}

std::span<const TrafficContact> World::TrafficContacts() const { return impl_->traffic_contacts; }

int World::AddVehicle(const VehicleParams& params, const RigidTransform2& X_MV) {
  const int index = static_cast<int>(impl_->vehicles.size());
  const Eigen::Vector2d p = X_MV.translation();
  impl_->vehicles.push_back(std::make_unique<internal::OdeVehicle>(
      params, index, impl_->world, impl_->vehicle_space, impl_->options.gravity_mps2, impl_->step_s,
      p.x(), p.y(), X_MV.yaw(), impl_->geometry.terrain.HeightAt(p.x(), p.y())));
  return index;
}

void World::SetCommand(int vehicle, const VehicleCommand& command) {
  AUTODRIVE_THROW_UNLESS(std::isfinite(command.throttle) && std::isfinite(command.steering),
                         "vehicle " << vehicle << ": a command must be finite, got throttle "
                                    << command.throttle << ", steering " << command.steering);
  impl_->vehicles.at(static_cast<std::size_t>(vehicle))->SetCommand(command);
}

void World::SetVelocity(int vehicle, const Eigen::Vector3d& v_M, const Eigen::Vector3d& w_M) {
  AUTODRIVE_THROW_UNLESS(v_M.allFinite() && w_M.allFinite(),
                         "vehicle " << vehicle << ": a velocity must be finite, got "
                                    << v_M.transpose() << " and " << w_M.transpose());
  impl_->vehicles.at(static_cast<std::size_t>(vehicle))->SetVelocity(v_M, w_M);
}

void World::Step() {
  Impl& w = *impl_;
  if (!w.failure.empty()) throw NumericalError(w.failure);
  for (std::size_t i = 0; i < w.vehicles.size(); ++i) {
    const std::string bad = w.vehicles[i]->CheckBeforeStep();
    if (!bad.empty()) {
      std::ostringstream message;
      message << "vehicle " << i << ": " << bad << " is beyond any plausible value before step "
              << w.steps + 1 << " (t = " << ToSeconds(time()) << " s)";
      w.failure = message.str();
      throw NumericalError(w.failure);
    }
  }
  for (auto& v : w.vehicles) v->PrepareStep();
  w.ChooseTraffic();
  w.traffic_contacts.clear();
  dSpaceCollide(w.vehicle_space, &w, &Impl::NearCallback);
  dSpaceCollide2(reinterpret_cast<dGeomID>(w.vehicle_space),
                 reinterpret_cast<dGeomID>(w.static_space), &w, &Impl::NearCallback);
  if (w.traffic_enabled > 0) {
    dSpaceCollide2(reinterpret_cast<dGeomID>(w.vehicle_space),
                   reinterpret_cast<dGeomID>(w.traffic_space), &w, &Impl::NearCallback);
  }
  dWorldStep(w.world, w.step_s);
  ++w.steps;
  for (std::size_t i = 0; i < w.vehicles.size(); ++i) {
    const std::string bad = w.vehicles[i]->FinishStep();
    if (!bad.empty() && w.failure.empty()) {
      std::ostringstream message;
      message << "vehicle " << i << ": " << bad << " is not finite after step " << w.steps
              << " (t = " << ToSeconds(time()) << " s)";
      w.failure = message.str();
    }
  }
  dJointGroupEmpty(w.contacts);
  if (!w.failure.empty()) throw NumericalError(w.failure);
  w.UpdateTimed();
}

void World::StepUntil(Duration until) {
  while (time() < until) Step();
}

const VehicleState& World::State(int vehicle) const {
  return impl_->vehicles.at(static_cast<std::size_t>(vehicle))->state();
}

void World::VehicleBox(int vehicle, Eigen::Isometry3d& X_MB,
                       Eigen::Vector3d& half_extents_m) const {
  impl_->vehicles.at(static_cast<std::size_t>(vehicle))->Box(X_MB, half_extents_m);
}

const VehicleParams& World::Params(int vehicle) const {
  return impl_->vehicles.at(static_cast<std::size_t>(vehicle))->params();
}

int World::vehicles() const { return static_cast<int>(impl_->vehicles.size()); }

Duration World::time() const { return impl_->steps * impl_->options.step; }

std::int64_t World::steps() const { return impl_->steps; }

const WorldOptions& World::options() const { return impl_->options; }

double World::GroundHeight(double x_m, double y_m) const {
  return impl_->geometry.terrain.HeightAt(x_m, y_m);
}

const StaticScene& World::Scene() const {
  if (!impl_->scene) impl_->scene.emplace(impl_->SceneGeometry(), impl_->options.scene.cell_size_m);
  return *impl_->scene;
}

const StaticGeometry& World::PermanentGeometry() const { return impl_->geometry; }

}  // namespace autodrive::vehicle_sim
