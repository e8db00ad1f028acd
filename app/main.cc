// monoplane: obstacle detection and mapping for a wheeled robot with one camera over a flat floor.
#include <malloc.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "app/commands.h"
#include "app/version.h"

int main(int argc, char** argv) {
  using namespace monoplane::app;
  // Every frame allocates and frees the same image-sized buffers (pyramids, gradients, maps of
  // 0.3-1.2 MB) in four threads. With glibc's defaults these go to mmap and back, and each frame
  // pays for their pages again in page faults (most of the kernel's 12.5 % of a run's CPU
  // samples). Kept in the heap, they are reused (tools/bench/throughput.sh: 62 -> 75-86 frames/s,
  // system time 3.4 -> 0.6-0.8 s, peak RSS +10 MB).
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  CLI::App app{
      "monoplane: see obstacles and build a lasting map with one camera over a flat floor"};
  app.set_version_flag("--version", std::string("monoplane ") + MONOPLANE_VERSION);
  app.require_subcommand(0, 1);
  int exit_code = kExitOk;
  RegisterRunCommand(&app, &exit_code);
  RegisterCheckCalibCommand(&app, &exit_code);
  RegisterCalibrateCommand(&app, &exit_code);
  RegisterEchoCommand(&app, &exit_code);
  RegisterMapCommands(&app, &exit_code);
  RegisterServeCommand(&app, &exit_code);
  RegisterReportCommand(&app, &exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitBadInput;
  }
  if (argc == 1) {
    std::cout << app.help();
  }
  return exit_code;
}
