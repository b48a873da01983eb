#pragma once
/// @file
/// The part of SUMO's C++ API that the co-simulation uses, behind one interface with two
/// backends: libsumo (SUMO inside this process: the default, fastest) and libtraci (SUMO as
/// its own process and TraCI server, so that sumo-gui can show it and further TraCI clients can
/// attach). libsumo and libtraci share their headers (the macro LIBTRACI switches the
/// namespace), so each backend is one translation unit (`sumo_api_impl.inc` compiled twice).
///
/// Everything here is in SUMO's frame (the network's scale, SUMO's angles); `CoSimulation`
/// maps it to the lab's. A SUMO error becomes `SumoError` with SUMO's message.

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace autodrive::traffic {

/// SUMO refused a call or failed (its message), or the TraCI connection broke.
class SumoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One vehicle as SUMO reports it after a step.
struct SumoVehicleState {
  std::string id;
  std::string type;
  double x = 0, y = 0;   ///< the front bumper's middle (SUMO metres)
  double angle_deg = 0;  ///< navigational: 0 north (+y), clockwise
  double speed_mps = 0;  ///< SUMO metres per second
  std::string lane;      ///< SUMO lane id (":junction_k_i" inside a junction)
  /// The front's distance from the lane's start (SUMO metres). Not read by `ReadVehicles` (it
  /// costs a call a vehicle): `LanePosition`.
  double lane_pos = 0;
  int signals = 0;      ///< SUMO's bits: 0 right blinker, 1 left, 3 brake light
  int route_index = 0;  ///< the edge of its route it is on; not read: `RouteIndex`
};

/// What happened in the last step.
struct SumoStepEvents {
  std::vector<std::string> departed;
  std::vector<std::string> arrived;
  std::vector<std::string> teleported;  ///< teleports started
  /// Collisions going on: (collider, victim) and SUMO's description (type, lane, position).
  /// SUMO reports a collision at every step the two overlap.
  struct Collision {
    std::string collider, victim, description;
  };
  std::vector<Collision> collisions;
};

/// A vehicle type's size (SUMO metres) and class (SUMO's vClass: passenger, bus, ...).
struct SumoTypeSize {
  double length = 0, width = 0, height = 0;
  std::string vclass;
};

class SumoApi {
 public:
  virtual ~SumoApi() = default;

  /// Starts SUMO with `args` (args[0] is the program: "sumo" or "sumo-gui" for TraCI; ignored by
  /// libsumo). TraCI: listens on `port` for `clients` clients in all (this one is client 1).
  virtual void Start(const std::vector<std::string>& args, int port, int clients) = 0;
  virtual void Close() = 0;
  /// Advances one step (to `until_s` if > 0).
  virtual void Step(double until_s) = 0;
  [[nodiscard]] virtual double Time() = 0;
  [[nodiscard]] virtual SumoStepEvents Events() = 0;

  virtual void AddRoute(const std::string& id, const std::vector<std::string>& edges) = 0;
  /// `depart` "now" or seconds; `lane` an index, "best", "free", "random"...; `pos` "base",
  /// "random_free" or metres.
  virtual void AddVehicle(const std::string& id, const std::string& route, const std::string& type,
                          const std::string& depart, const std::string& lane,
                          const std::string& pos, const std::string& speed) = 0;
  virtual void SetRoute(const std::string& id, const std::vector<std::string>& edges) = 0;
  [[nodiscard]] virtual std::vector<std::string> Route(const std::string& id) = 0;
  /// Places the vehicle's front bumper at (x, y) with `angle_deg` (navigational), on the lane
  /// nearest to it: of its route's edges and the internal lanes between them when `keep_route`
  /// (keepRoute 3), else of any edge, its route then replaced by that lane's (keepRoute 2).
  /// `edge`'s lane `lane` is only a hint: SUMO 1.15 took the lane nearest the point whichever
  /// lane was named, in every case tried (and, without `keep_route`, whatever the angle).
  virtual void MoveToXY(const std::string& id, const std::string& edge, int lane, double x,
                        double y, double angle_deg, bool keep_route) = 0;
  [[nodiscard]] virtual double LaneLength(const std::string& lane) = 0;
  /// Sets the speed SUMO reports and uses for followers (m/s; < 0 gives control back).
  virtual void SetSpeed(const std::string& id, double speed) = 0;
  /// SUMO's speed mode bits (e.g. 0: no checks at all, for externally moved vehicles).
  virtual void SetSpeedMode(const std::string& id, int mode) = 0;
  virtual void Remove(const std::string& id) = 0;
  [[nodiscard]] virtual std::vector<std::string> VehicleIds() = 0;

  /// Reads every vehicle in the network after a step into `out` (resized): id, type,
  /// position, angle, speed, lane, signals.
  virtual void ReadVehicles(std::vector<SumoVehicleState>& out) = 0;
  [[nodiscard]] virtual double LanePosition(const std::string& id) = 0;
  [[nodiscard]] virtual int RouteIndex(const std::string& id) = 0;
  [[nodiscard]] virtual SumoTypeSize TypeSize(const std::string& type) = 0;

  virtual void SetLightState(const std::string& tls, const std::string& state) = 0;
  [[nodiscard]] virtual std::string LightState(const std::string& tls) = 0;
  /// SUMO's time of the light's next switch of its own (s): a light set from outside is held,
  /// its switch far away and not moved by the next state set.
  [[nodiscard]] virtual double LightNextSwitch(const std::string& tls) = 0;
  /// The internal (via) lanes of each link of a lane: (to lane, via lane).
  [[nodiscard]] virtual std::vector<std::pair<std::string, std::string>> Links(
      const std::string& lane) = 0;
  /// The lane that follows an internal lane (its single link's via or target lane).
  [[nodiscard]] virtual std::string NextLane(const std::string& internal_lane) = 0;
  /// Halting vehicles on a lane (speed < 0.1 m/s), SUMO's count.
  [[nodiscard]] virtual int HaltingNumber(const std::string& lane) = 0;
};

/// SUMO in this process (libsumo). One simulation per process: a second started one throws.
std::unique_ptr<SumoApi> MakeLibsumoApi();
/// SUMO as a TraCI server in its own process (libtraci).
std::unique_ptr<SumoApi> MakeTraciApi();

}  // namespace autodrive::traffic
