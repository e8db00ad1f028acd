// Runs the monoplane-eval program on small generated inputs: exit codes, JSON values, messages.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "tools/eval/eval_test_fixtures.h"

namespace monoplane::eval {
namespace {

namespace fs = std::filesystem;

const std::string kProgram = std::string(MONOPLANE_BINARY_DIR) + "/tools/eval/monoplane-eval";

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

RunResult RunEval(const std::string& arguments) {
  RunResult result;
  FILE* pipe = popen((kProgram + " " + arguments + " 2>&1").c_str(), "r");
  if (!pipe) return result;
  char buffer[4096];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.output.append(buffer, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// The number after the first occurrence of `"key": ` at or after `after` in a JSON text.
double JsonNumber(const std::string& json, const std::string& key, const std::string& after = "") {
  std::size_t pos = after.empty() ? 0 : json.find(after);
  if (pos == std::string::npos) return NAN;
  pos = json.find("\"" + key + "\": ", pos);
  if (pos == std::string::npos) return NAN;
  return std::strtod(json.c_str() + pos + key.size() + 4, nullptr);
}

class EvalCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("monoplane_eval_cli_test_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(EvalCliTest, TrajectoryJsonAndTable) {
  {
    std::ofstream gt(Path("gt.txt")), pred(Path("pred.txt"));
    for (int i = 0; i <= 20; ++i) {
      gt << 0.1 * i << " " << 0.1 * i << " 0 0 0 0 0 1\n";
      pred << 0.1 * i + 0.005 << " " << 0.1 * i + 0.3 << " 0.4 0 0 0 0 1\n";
    }
  }
  const RunResult json =
      RunEval("traj --pred " + Path("pred.txt") + " --gt " + Path("gt.txt") + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.output;
  EXPECT_EQ(JsonNumber(json.output, "matched_poses"), 21);
  EXPECT_NEAR(JsonNumber(json.output, "rmse", "\"ate_m\""), 0.5, 1e-6);
  EXPECT_NEAR(JsonNumber(json.output, "rmse", "\"ate_aligned_m\""), 0.0, 1e-6);
  EXPECT_NEAR(JsonNumber(json.output, "gt_path_length_m"), 2.0, 1e-6);
  EXPECT_NEAR(JsonNumber(json.output, "rpe_translation_percent"), 0.0, 1e-6);

  const RunResult table = RunEval("traj --pred " + Path("pred.txt") + " --gt " + Path("gt.txt"));
  ASSERT_EQ(table.exit_code, 0);
  EXPECT_NE(table.output.find("ATE (m), no alignment:   rmse 0.5000"), std::string::npos)
      << table.output;

  // A time offset beyond --max-dt leaves nothing to score: invalid input.
  const RunResult none =
      RunEval("traj --pred " + Path("pred.txt") + " --gt " + Path("gt.txt") + " --max-dt 0.001");
  EXPECT_EQ(none.exit_code, 2) << none.output;
  EXPECT_NE(none.output.find("max_dt"), std::string::npos) << none.output;
}

TEST_F(EvalCliTest, MalformedTrajectoryExitsTwoWithOneLineNamingTheFile) {
  std::ofstream(Path("bad.txt")) << "0.0 1 2 3\n";
  std::ofstream(Path("gt.txt")) << "0.0 0 0 0 0 0 0 1\n0.1 0.1 0 0 0 0 0 1\n";
  const RunResult r = RunEval("traj --pred " + Path("bad.txt") + " --gt " + Path("gt.txt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output.find(Path("bad.txt") + ":1: expected 8 finite numbers"), 16u) << r.output;
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << "one line: " << r.output;
}

TEST_F(EvalCliTest, GridShiftWithTolerance) {
  const auto write_map = [&](const std::string& name, int wall_col) {
    cv::Mat image(40, 40, CV_8UC1, cv::Scalar(254));
    for (int r = 5; r < 35; ++r) image.at<std::uint8_t>(r, wall_col) = 0;
    ASSERT_TRUE(cv::imwrite(Path(name + ".pgm"), image));
    std::ofstream(Path(name + ".yaml"))
        << "image: " << name << ".pgm\nmode: trinary\nresolution: 0.05\norigin: [0, 0, 0]\n"
        << "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  };
  write_map("gt", 10);
  write_map("pred", 12);
  const std::string args =
      "grid --pred " + Path("pred.yaml") + " --gt " + Path("gt.yaml") + " --json";
  const RunResult strict = RunEval(args + " --tolerance 1");
  ASSERT_EQ(strict.exit_code, 0) << strict.output;
  EXPECT_EQ(JsonNumber(strict.output, "precision"), 0.0);
  EXPECT_EQ(JsonNumber(strict.output, "dangerous"), 30);
  const RunResult tolerant = RunEval(args + " --tolerance 2");
  ASSERT_EQ(tolerant.exit_code, 0) << tolerant.output;
  EXPECT_EQ(JsonNumber(tolerant.output, "precision"), 1.0);
  EXPECT_EQ(JsonNumber(tolerant.output, "recall"), 1.0);
  EXPECT_EQ(JsonNumber(tolerant.output, "f1"), 1.0);
  EXPECT_EQ(JsonNumber(tolerant.output, "unknown_share"), 0.0);

  const RunResult negative = RunEval(args + " --tolerance -1");
  EXPECT_EQ(negative.exit_code, 2) << negative.output;
}

TEST_F(EvalCliTest, LabelsJsonAndUnreadableImage) {
  std::string error;
  ASSERT_TRUE(WriteLabelSequenceFixture(dir_, &error)) << error;
  const std::string args = "labels --pred " + Path("pred") + " --gt " + Path("seq");
  const RunResult json = RunEval(args + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.output;
  EXPECT_EQ(JsonNumber(json.output, "frames_scored"), 1);
  EXPECT_EQ(JsonNumber(json.output, "frames_missing"), 1);
  EXPECT_NEAR(JsonNumber(json.output, "obstacle_recall", "\"overall\""), 1.0 / 3.0, 1e-6);
  EXPECT_NEAR(JsonNumber(json.output, "coverage", "\"overall\""), 9.0 / 11.0, 1e-6);
  EXPECT_NEAR(JsonNumber(json.output, "height_error_median_m", "\"overall\""), 0.035, 1e-6);
  const RunResult table = RunEval(args);
  ASSERT_EQ(table.exit_code, 0);
  EXPECT_NE(table.output.find("overall"), std::string::npos);

  std::ofstream(dir_ / "pred/labels/000001.png") << "not a png";
  const RunResult bad = RunEval(args);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find(Path("pred/labels/000001.png") + ": cannot read"), std::string::npos)
      << bad.output;
}

TEST_F(EvalCliTest, TracksJsonTableAndMalformedLine) {
  fs::create_directories(dir_ / "seq/gt");
  fs::create_directories(dir_ / "pred/moving");
  {
    // Two frames, the robot at the origin facing +x; one mover 2 m ahead, in view.
    std::ofstream(Path("seq/gt/trajectory.txt")) << "0.0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n";
    std::ofstream(Path("seq/gt/movers.txt"))
        << "# frame_index time_s mover_index x_m y_m vx_mps vy_mps radius_m in_view\n"
        << "0 0.0 0 2 0 0 1 0.22 1\n1 0.1 0 2 0.1 0 1 0.22 1\n";
    std::ofstream(Path("pred/moving/000000.txt")) << "3 2.1 0 0 1 0.2\n4 1 -1 0 0 0.2\n";
  }
  const std::string args = "tracks --pred " + Path("pred") + " --gt " + Path("seq");
  const RunResult json = RunEval(args + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.output;
  EXPECT_EQ(JsonNumber(json.output, "frames_missing"), 1);
  EXPECT_EQ(JsonNumber(json.output, "visible_frames", "\"movers\""), 2);
  EXPECT_NEAR(JsonNumber(json.output, "detected_share", "\"overall\""), 0.5, 1e-9);
  EXPECT_NEAR(JsonNumber(json.output, "position_error_median_m", "\"overall\""), 0.1, 1e-9);
  EXPECT_EQ(JsonNumber(json.output, "main_id"), 3);
  EXPECT_EQ(JsonNumber(json.output, "false_objects"), 1);
  EXPECT_EQ(JsonNumber(json.output, "frames_with_false_objects_share"), 1.0);
  const RunResult table = RunEval(args);
  ASSERT_EQ(table.exit_code, 0) << table.output;
  EXPECT_NE(table.output.find("false objects: 1"), std::string::npos) << table.output;

  std::ofstream(Path("pred/moving/000001.txt")) << "3 2.1 0 0 1\n";
  const RunResult bad = RunEval(args);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_EQ(bad.output.find(Path("pred/moving/000001.txt") + ":1: expected"), 16u) << bad.output;
  EXPECT_EQ(bad.output.find('\n'), bad.output.size() - 1) << "one line: " << bad.output;
}

TEST_F(EvalCliTest, MissingSubcommandOrOptionIsBadInput) {
  EXPECT_EQ(RunEval("").exit_code, 2);
  EXPECT_EQ(RunEval("traj --pred x.txt").exit_code, 2);
  EXPECT_EQ(
      RunEval("kitti --pred " + Path("p") + " --kitti " + Path("k") + " --frames 5-2").exit_code,
      2);
}

}  // namespace
}  // namespace monoplane::eval
