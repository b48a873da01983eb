#pragma once
/// @file
/// The subcommands of `autodrive-eye`, each in its own file: `Add...` registers one on the
/// program's CLI11 app with its options and its callback.

#include <CLI/CLI.hpp>

namespace autodrive::eye::cli {

/// `calibrate`: intrinsics and distortion from photos of a chessboard (calibrate_command.cpp).
void AddCalibrate(CLI::App& app);
/// `register`: each camera's pose in the map from the reference tags (localize_commands.cpp).
void AddRegister(CLI::App& app);
/// `localize`: the fleet's poses from frames on disk, to CSV (localize_commands.cpp).
void AddLocalize(CLI::App& app);
/// `run`: the online localiser on DDS (run_command.cpp).
void AddRun(CLI::App& app);

}  // namespace autodrive::eye::cli
