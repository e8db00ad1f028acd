#pragma once
// The built-in demo of `monoplane run` (no input): the office scene rendered with its ground
// truth, and the scores of a run's per-frame outputs against it. The program needs only these two
// calls; the simulator and the evaluator stay behind them.

#include <optional>
#include <string>

namespace monoplane::demo {

// Renders the built-in office scene (compiled in, tests/data/scenes/office.yaml) into
// `sequence_dir` (images, times.txt, calib.yaml, gt/). Errors name the file or the scene key.
bool RenderDemoSequence(const std::string& sequence_dir, std::string* error);

// Per-pixel scores of a run's outputs (`frames_dir`, as `run --frames-out` writes) against the
// rendered ground truth, over all frames. Unset when nothing was there to score.
struct DemoScores {
  int frames_scored = 0;
  std::optional<double> obstacle_recall;            // obstacles >= 5 cm tall labelled obstacle
  std::optional<double> floor_false_obstacle_rate;  // floor labelled obstacle (tools/eval)
  std::optional<double> coverage;                   // pixels not unknown
  std::optional<double> dangerous_rate;             // obstacle labelled floor
  std::optional<double> height_error_median_m;
};
bool ScoreDemo(const std::string& frames_dir, const std::string& sequence_dir, DemoScores* scores,
               std::string* error);

}  // namespace monoplane::demo
