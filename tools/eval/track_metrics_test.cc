#include "tools/eval/track_metrics.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace monoplane::eval {
namespace {

namespace fs = std::filesystem;

class TrackMetricsFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("monoplane_track_metrics_test_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "seq/gt");
    fs::create_directories(dir_ / "pred/moving");
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  void WritePrediction(int frame, const std::string& text) const {
    char name[32];
    std::snprintf(name, sizeof(name), "pred/moving/%06d.txt", frame);
    std::ofstream(dir_ / name) << text;
  }

  // 12 frames, 0.1 s apart; the robot faces map +y (yaw 90 deg) at (0, 0.1 i). Mover 0 walks at
  // map (-1, 2 + 0.1 i), i.e. always 2 m ahead and 1 m to the left of the base, velocity map
  // (0, 0.5) = base (0.5, 0); it is in view in frames 0..9 only. Mover 1 is in view but 6 m away.
  void WriteSequence() const {
    std::ofstream trajectory(dir_ / "seq/gt/trajectory.txt");
    std::ofstream movers(dir_ / "seq/gt/movers.txt");
    movers << "# frame_index time_s mover_index x_m y_m vx_mps vy_mps radius_m in_view\n";
    const double q = std::sqrt(0.5);
    for (int i = 0; i < 12; ++i) {
      char line[200];
      std::snprintf(line, sizeof(line), "%.6f 0 %.6f 0 0 0 %.9f %.9f\n", 0.1 * i, 0.1 * i, q, q);
      trajectory << line;
      std::snprintf(line, sizeof(line), "%d %.6f 0 -1 %.6f 0 0.5 0.22 %d\n", i, 0.1 * i,
                    2 + 0.1 * i, i < 10 ? 1 : 0);
      movers << line;
      std::snprintf(line, sizeof(line), "%d %.6f 1 0 %.6f 0 0 0.25 1\n", i, 0.1 * i, 6 + 0.1 * i);
      movers << line;
    }
  }

  fs::path dir_;
};

TEST_F(TrackMetricsFiles, OffsetIdSwitchFalseObjectAndMissingFrame) {
  WriteSequence();
  // Mover 0 is at base (2, 1). Predictions 0.1 m to its right (map +x = base -y) with a velocity
  // error of 0.2 m/s; frame 9 0.3 m off with the exact velocity; frame 5 has no file; the id
  // switches from 7 to 8 at frame 7; frame 3 holds a false object; frames 10, 11 hold nothing.
  for (int i = 0; i < 12; ++i) {
    if (i == 5) continue;
    std::string text = "# id x_m y_m vx_mps vy_mps radius_m\n";
    if (i < 9) text += std::string(i < 7 ? "7" : "8") + " 2.0 0.9 0.5 0.2 0.2\n";
    if (i == 9) text += "8 2.0 0.7 0.5 0.0 0.2\n";
    if (i == 3) text += "99 0.5 -1.5 0 0 0.3\n";
    WritePrediction(i, text);
  }
  TrackEvalResult r;
  std::string error;
  ASSERT_TRUE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error))
      << error;
  EXPECT_EQ(r.frames, 12);
  EXPECT_EQ(r.frames_with_output, 11);
  EXPECT_EQ(r.frames_missing, 1);
  ASSERT_EQ(r.movers.size(), 2u);

  const TrackMetrics& m = r.movers[0];
  EXPECT_EQ(m.mover, 0);
  EXPECT_EQ(m.visible_frames, 10);
  EXPECT_EQ(m.detected_frames, 9);  // frame 5 has no output
  EXPECT_NEAR(*m.detected_share, 0.9, 1e-12);
  // Errors 0.1 x 8 and 0.3: median 0.1; p95 at rank 0.95 * 8 = 7.6: 0.1 + 0.6 * 0.2.
  EXPECT_NEAR(*m.position_error_median_m, 0.1, 1e-6);
  EXPECT_NEAR(*m.position_error_p95_m, 0.22, 1e-6);
  EXPECT_NEAR(*m.velocity_error_median_mps, 0.2, 1e-6);
  EXPECT_EQ(*m.main_id, 7);
  EXPECT_EQ(m.consistent_frames, 6);  // id 7 in frames 0-4 and 6
  EXPECT_NEAR(*m.id_consistency, 0.6, 1e-12);

  const TrackMetrics& far = r.movers[1];
  EXPECT_EQ(far.visible_frames, 0);
  EXPECT_FALSE(far.detected_share);
  EXPECT_FALSE(far.position_error_median_m);
  EXPECT_FALSE(far.id_consistency);
  EXPECT_FALSE(far.main_id);

  EXPECT_EQ(r.overall.visible_frames, 10);
  EXPECT_EQ(r.overall.detected_frames, 9);
  EXPECT_NEAR(*r.overall.detected_share, 0.9, 1e-12);
  EXPECT_NEAR(*r.overall.position_error_median_m, 0.1, 1e-6);
  EXPECT_NEAR(*r.overall.position_error_p95_m, 0.22, 1e-6);
  EXPECT_NEAR(*r.overall.velocity_error_median_mps, 0.2, 1e-6);
  EXPECT_NEAR(*r.overall.id_consistency, 0.6, 1e-12);

  EXPECT_EQ(r.false_objects, 1);
  EXPECT_EQ(r.frames_with_false_objects, 1);
  EXPECT_NEAR(*r.frames_with_false_objects_share, 1.0 / 11.0, 1e-12);
  EXPECT_EQ(r.false_objects_near_unscored_movers, 0);

  // A wider range scores mover 1 too (never detected); a tight gate rejects the 0.3 m match.
  TrackEvalOptions options;
  options.max_range_m = 7.0;
  options.gate_m = 0.2;
  ASSERT_TRUE(EvaluateTrackSequence(Path("pred"), Path("seq"), options, &r, &error)) << error;
  EXPECT_EQ(r.movers[1].visible_frames, 12);
  EXPECT_NEAR(*r.movers[1].detected_share, 0.0, 1e-12);
  EXPECT_EQ(r.movers[0].detected_frames, 8);
  EXPECT_EQ(r.overall.visible_frames, 22);
  EXPECT_EQ(r.false_objects, 2);  // the far one and frame 9's
  EXPECT_EQ(r.false_objects_near_unscored_movers, 0);
}

TEST(TrackMetrics, GreedyMatchingTakesTheNearestPairFirst) {
  // Movers A (0, 0) and B (0.4, 0); predictions P (0.3, 0) and Q (-0.3, 0). Nearest first: B-P
  // (0.1), then A-Q (0.3) since P is taken; B-Q (0.7) is beyond the gate anyway.
  TrackFrame frame;
  frame.has_output = true;
  GtMoverState a, b, hidden;
  a.mover = 0;
  a.in_view = true;
  b.mover = 1;
  b.position_m = {0.4, 0.0};
  b.in_view = true;
  hidden.mover = 2;
  hidden.position_m = {0.0, 3.0};
  hidden.in_view = false;  // out of view: not scored, but a prediction on it is "near" it
  frame.movers = {a, b, hidden};
  TrackedObject p, q, on_hidden;
  p.id = 1;
  p.position_m = {0.3, 0.0};
  q.id = 2;
  q.position_m = {-0.3, 0.0};
  on_hidden.id = 3;
  on_hidden.position_m = {0.1, 3.0};
  frame.objects = {p, q, on_hidden};
  const TrackEvalResult r = EvaluateTracks({frame}, 0, TrackEvalOptions{});
  ASSERT_EQ(r.movers.size(), 3u);
  EXPECT_EQ(*r.movers[0].main_id, 2);
  EXPECT_NEAR(*r.movers[0].position_error_median_m, 0.3, 1e-12);
  EXPECT_EQ(*r.movers[1].main_id, 1);
  EXPECT_NEAR(*r.movers[1].position_error_median_m, 0.1, 1e-12);
  EXPECT_EQ(r.movers[2].visible_frames, 0);
  EXPECT_EQ(r.false_objects, 1);
  EXPECT_EQ(r.false_objects_near_unscored_movers, 1);

  // With a minimum speed, a mover standing still is not scored (a static obstacle then), and
  // the prediction on it is near an unscored mover, not a plain false object.
  frame.movers[0].velocity_mps = {0.0, 0.0};
  frame.movers[1].velocity_mps = {0.6, 0.0};
  TrackEvalOptions moving;
  moving.min_speed_mps = 0.1;
  const TrackEvalResult m = EvaluateTracks({frame}, 0, moving);
  EXPECT_EQ(m.movers[0].visible_frames, 0);
  EXPECT_EQ(m.movers[1].visible_frames, 1);
  EXPECT_EQ(m.false_objects, 2);
  EXPECT_EQ(m.false_objects_near_unscored_movers, 2);
  moving.min_speed_mps = -1.0;
  std::string error;
  EXPECT_FALSE(moving.IsValid(&error));
  EXPECT_NE(error.find("min_speed_mps"), std::string::npos) << error;
}

TEST_F(TrackMetricsFiles, BadInputNamesTheFileAndLine) {
  WriteSequence();
  WritePrediction(0, "# comment\n7 2.0 0.9 0.5 0.2 0.2\n7 2.0 zero 0.5 0.2 0.2\n");
  TrackEvalResult r;
  std::string error;
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error));
  EXPECT_EQ(error.rfind(Path("pred/moving/000000.txt") + ":3: expected", 0), 0u) << error;

  WritePrediction(0, "7.5 2.0 0.9 0.5 0.2 0.2\n");  // the id must be an integer
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error));
  EXPECT_EQ(error.rfind(Path("pred/moving/000000.txt") + ":1: expected", 0), 0u) << error;
  WritePrediction(0, "7 2.0 0.9 0.5 0.2 0.2 extra\n");
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error));
  EXPECT_EQ(error.rfind(Path("pred/moving/000000.txt") + ":1: expected", 0), 0u) << error;
  WritePrediction(0, "");

  std::ofstream(dir_ / "seq/gt/movers.txt", std::ios::app) << "12 1.2 0 0 0 0 0 0.2 1\n";
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error));
  EXPECT_EQ(error.rfind(Path("seq/gt/movers.txt") + ":26: frame 12 has no line", 0), 0u) << error;

  std::ofstream(dir_ / "seq/gt/movers.txt") << "# header\n0 0.0 0 1 2 0 0 0.2 2\n";
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error));
  EXPECT_EQ(error.rfind(Path("seq/gt/movers.txt") + ":2: ", 0), 0u) << error;

  std::ofstream(dir_ / "seq/gt/movers.txt") << "0 0.5 0 1 2 0 0 0.2 1\n";  // frame 0 is at 0 s
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error));
  EXPECT_EQ(error.rfind(Path("seq/gt/movers.txt") + ":1: frame 0 at 0.5", 0), 0u) << error;

  fs::remove(dir_ / "seq/gt/movers.txt");
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), TrackEvalOptions{}, &r, &error));
  EXPECT_EQ(error, Path("seq/gt/movers.txt") + ": cannot open the movers file");

  TrackEvalOptions bad;
  bad.gate_m = 0.0;
  EXPECT_FALSE(EvaluateTrackSequence(Path("pred"), Path("seq"), bad, &r, &error));
  EXPECT_EQ(error.rfind("TrackEvalOptions::gate_m", 0), 0u) << error;
}

}  // namespace
}  // namespace monoplane::eval
