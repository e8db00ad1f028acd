#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "perception/geometry/timestamp.h"

namespace monoplane::app {

// Exit codes of the monoplane program.
inline constexpr int kExitOk = 0;
inline constexpr int kExitError = 1;     // an internal failure
inline constexpr int kExitBadInput = 2;  // the user's input (file, option, config) is unusable
inline constexpr int kExitInterrupted = 130;
inline constexpr int kExitTerminated = 143;  // 128 + SIGTERM, as a shell reports it
inline constexpr int kExitHungUp = 129;      // 128 + SIGHUP

// Each command registers its subcommand; the callback stores the exit code in *exit_code.
void RegisterCheckCalibCommand(CLI::App* app, int* exit_code);
void RegisterCalibrateCommand(CLI::App* app, int* exit_code);  // app/calibrate_command.cc
void RegisterRunCommand(CLI::App* app, int* exit_code);        // app/run_cli.cc: run, config
void RegisterEchoCommand(CLI::App* app, int* exit_code);       // app/echo_command.cc
void RegisterMapCommands(CLI::App* app,
                         int* exit_code);  // app/map_commands.cc: info, query, export
void RegisterServeCommand(CLI::App* app, int* exit_code);   // app/serve_command.cc
void RegisterReportCommand(CLI::App* app, int* exit_code);  // app/report_command.cc

// A wall-clock time for people: "2026-12-02 07:09:55 UTC" (app/map_commands.cc).
std::string UtcTime(TimestampNs ns);

// `monoplane report MAP --out HTML [--frames DIR --panels N]`, for the demo: prints the report's
// line (or the error) and returns the exit code.
int WriteMapReport(const std::string& map_path, const std::string& html_path,
                   const std::string& frames_dir, int panels);

}  // namespace monoplane::app
