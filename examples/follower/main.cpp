// autodrive-example-follower: see README.md beside this file, and examples/v2i/agent.h.
#include "examples/v2i/agent.h"

int main(int argc, char** argv) {
  return autodrive::examples::RunAgent(argc, argv, autodrive::examples::AgentKind::kFollower);
}
