// monoplane-sim: renders a synthetic scene into an input folder with ground truth.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "tools/sim/scene.h"
#include "tools/sim/sequence.h"

int main(int argc, char** argv) {
  CLI::App app{
      "monoplane-sim: render a synthetic scene (YAML) into images/, times.txt, calib.yaml "
      "and gt/ (labels, height, depth, trajectory, movers, map, OctoMap)"};
  std::string scene_path, out_dir;
  int frames = -1;
  long long seed = -1;
  app.add_option("scene", scene_path, "scene YAML file (schema: tools/sim/README.md)")->required();
  app.add_option("--out", out_dir, "output folder (created)")->required();
  app.add_option("--frames", frames, "number of frames (default: the scene's)")
      ->check(CLI::Range(1, 1000000));
  app.add_option("--seed", seed, "random seed (default: the scene's)")
      ->check(CLI::Range(0LL, 4294967295LL));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;  // --help: 0; bad arguments: 2
  }

  monoplane::sim::Scene scene;
  std::string error;
  if (!monoplane::sim::LoadSceneFile(scene_path, &scene, &error)) {
    std::fprintf(stderr, "monoplane-sim: %s\n", error.c_str());
    return 2;
  }
  monoplane::sim::SequenceOptions options;
  options.frames = frames;
  if (seed >= 0) options.seed = static_cast<unsigned>(seed);
  if (!monoplane::sim::GenerateSequence(scene, out_dir, options, &error)) {
    std::fprintf(stderr, "monoplane-sim: %s\n", error.c_str());
    return 1;
  }
  std::printf("monoplane-sim: wrote %d frames to %s\n", frames > 0 ? frames : scene.NumFrames(),
              out_dir.c_str());
  return 0;
}
