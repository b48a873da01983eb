// SumoApi on libsumo: SUMO in this process.
#include <libsumo/libsumo.h>

#include "traffic/sumo_api_impl.inc"

namespace autodrive::traffic {
std::unique_ptr<SumoApi> MakeLibsumoApi() { return std::make_unique<Backend>(); }
}  // namespace autodrive::traffic
