#include "scm/city_bundle.h"

namespace autodrive::scm {

SupervisionParams SupervisionParamsOf(const City& city) {
  SupervisionParams p;
  p.city = city.config.name;
  p.timeout = city.device_timeout;
  p.mismatch = city.device_mismatch;
  p.wait_for_lights = city.config.devices.wait_for_lights;
  p.recover_after = city.config.devices.recover_s;
  p.max_recoveries_per_hour = city.config.devices.max_recoveries_per_hour;
  return p;
}

CityBundle::CityBundle(std::unique_ptr<City> city, const dds::Participant& participant,
                       ClockKind clock, SignalCommandWriters& writers,
                       std::vector<IntersectionStateRecord> restore_states,
                       std::uint32_t map_revision)
    : restore(std::move(restore_states)) {
  const City& c = *city;
  map = BuildMapMessages(c, map_revision);
  runtime = std::make_unique<CityRuntime>(std::move(city));
  const City& owned = runtime->city();
  supervisor = std::make_unique<DeviceSupervisor>(*runtime, SupervisionParamsOf(owned));
  devices = std::make_unique<DeviceTable>(*runtime, owned.device_timeout, MonoTime{});
  lights = std::make_unique<LightCommander>(writers, *runtime);
  fleet = std::make_unique<FleetRegistry>(
      owned.map, FleetRegistryParams{owned.fleet_staleness, 0.05, kPi / 3});
  std::vector<VehicleId> vehicles;
  for (const auto& name : owned.config.fleet.vehicles) vehicles.push_back(ParseVehicleName(name));
  sources.push_back(std::make_unique<IpsSource>(participant, vehicles, clock));
  if (owned.config.fleet.eye) sources.push_back(std::make_unique<EyeSource>(participant));
  if (owned.config.fleet.traffic) {
    sources.push_back(std::make_unique<TrafficSource>(participant));
  }
  (void)c;
}

CityBundle::~CityBundle() {
  // The parts that borrow the city's map and model go first.
  sources.clear();
  fleet.reset();
  lights.reset();
  devices.reset();
  supervisor.reset();
  runtime.reset();
}

void CityBundle::Start(const ClockReading& now) {
  runtime->Start(now, restore);
  lights->Forget();
  supervisor = std::make_unique<DeviceSupervisor>(*runtime, SupervisionParamsOf(runtime->city()));
  devices = std::make_unique<DeviceTable>(*runtime, runtime->city().device_timeout, now.mono);
}

}  // namespace autodrive::scm
