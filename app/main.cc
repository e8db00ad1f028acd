// monoplane: obstacle detection and mapping for a wheeled robot with one camera over a flat floor.
#include <CLI/CLI.hpp>
#include <iostream>

#include "app/commands.h"
#include "app/version.h"

int main(int argc, char** argv) {
  using namespace monoplane::app;
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
