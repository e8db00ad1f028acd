#include "tools/demo/demo.h"

#include "tools/demo/demo_scene.h"
#include "tools/eval/label_metrics.h"
#include "tools/sim/scene.h"
#include "tools/sim/sequence.h"

namespace monoplane::demo {

bool RenderDemoSequence(const std::string& sequence_dir, std::string* error) {
  sim::Scene scene;
  if (!sim::ParseSceneYaml(kDemoSceneYaml, &scene, error)) {
    *error = "built-in scene: " + *error;
    return false;
  }
  return sim::GenerateSequence(scene, sequence_dir, sim::SequenceOptions(), error);
}

bool ScoreDemo(const std::string& frames_dir, const std::string& sequence_dir, DemoScores* scores,
               std::string* error) {
  eval::LabelEvalResult labels;
  if (!eval::EvaluateLabelSequence(frames_dir, sequence_dir, eval::LabelEvalOptions{}, &labels,
                                   error)) {
    return false;
  }
  const auto& o = labels.overall;
  *scores = DemoScores{labels.frames_scored, o.obstacle_recall, o.floor_false_obstacle_rate,
                       o.coverage,           o.dangerous_rate,  o.height_error_median_m};
  return true;
}

}  // namespace monoplane::demo
