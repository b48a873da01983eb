// SumoApi on libtraci: SUMO as a TraCI server in its own process.
#define LIBTRACI 1
#include <libsumo/libtraci.h>

#include "traffic/sumo_api_impl.inc"

namespace autodrive::traffic {
std::unique_ptr<SumoApi> MakeTraciApi() { return std::make_unique<Backend>(); }
}  // namespace autodrive::traffic
