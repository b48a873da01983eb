// autodrive-eye: the overhead AprilTag localiser. Subcommands: calibrate (a camera's
// intrinsics from chessboard photos), register (each camera's pose in the map from the
// reference tags), localize (the fleet's poses from frames on disk), run (online on DDS). See
// docs/eye.md.
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "eye/commands.h"

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-eye: the overhead AprilTag localiser of the lab's fleet: calibrates cameras, "
      "registers them to the map with the reference tags on the ground, and localises every car "
      "by its roof tag. See docs/eye.md."};
  app.require_subcommand(1);
  autodrive::eye::cli::AddCalibrate(app);
  autodrive::eye::cli::AddRegister(app);
  autodrive::eye::cli::AddLocalize(app);
  autodrive::eye::cli::AddRun(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-eye: %s\n", e.what());
    return 1;
  }
  return 0;
}
