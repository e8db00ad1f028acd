// Render time of one 640x480 frame of the named test scenes (one core).
#include <benchmark/benchmark.h>

#include <string>

#include "tools/sim/renderer.h"
#include "tools/sim/scene.h"

namespace {

void BM_RenderScene(benchmark::State& state, const std::string& name, int edge_samples = 4) {
  monoplane::sim::Scene scene;
  std::string error;
  if (!monoplane::sim::LoadSceneFile(
          std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/scenes/" + name + ".yaml", &scene,
          &error)) {
    state.SkipWithError(error.c_str());
    return;
  }
  const monoplane::sim::SceneRenderer renderer(scene, scene.calibration);
  monoplane::sim::RenderOptions options;
  options.edge_samples = edge_samples;
  int frame = 0;
  for (auto _ : state) {
    const double t = (frame++ % 100) / scene.fps;
    benchmark::DoNotOptimize(renderer.RenderAtTime(t, options));
  }
}

BENCHMARK_CAPTURE(BM_RenderScene, office, std::string("office"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderScene, office_no_edge_aa, std::string("office"), 1)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderScene, corridor, std::string("corridor"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderScene, newspaper_on_carpet, std::string("newspaper_on_carpet"))
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderScene, person_crossing, std::string("person_crossing"))
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
