// The run pipeline without the command line: Run() on a rendered sequence (its summary against the
// input and against the map it wrote), and the map sink's one-writer rule.
#include "app/run_pipeline.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <numeric>

#include "app/commands.h"
#include "storage/map_database.h"
#include "tools/sim/scene.h"
#include "tools/sim/sequence.h"

namespace monoplane::app {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 40;

class RunPipelineTest : public ::testing::Test {
 protected:
  // 40 frames of the corridor (1.3 m driven), and a copy whose frame 10 is not an image.
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("monoplane_run_pipeline_" + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    sim::Scene scene;
    std::string error;
    ASSERT_TRUE(
        sim::LoadSceneFile(MONOPLANE_SOURCE_DIR "/tests/data/scenes/corridor.yaml", &scene, &error))
        << error;
    sim::SequenceOptions options;
    options.frames = kFrames;
    options.seed = 3;
    ASSERT_TRUE(sim::GenerateSequence(scene, Sequence(), options, &error)) << error;
    fs::copy(Sequence(), Broken(), fs::copy_options::recursive);
    std::ofstream(Broken() + "/images/000010.png") << "not a png";
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static std::string Sequence() { return (*dir_ / "seq").string(); }
  static std::string Broken() { return (*dir_ / "broken").string(); }
  static std::string MapPath(const std::string& name) { return (*dir_ / name).string(); }

  static RunRequest Request(const std::string& input, const std::string& map_path = "") {
    RunRequest request;
    request.input_path = input;
    request.map_path = map_path;
    request.quiet = true;
    return request;
  }

  // The runs of a map, opened for reading as `info` opens it.
  static std::vector<RunInfo> RunsIn(const std::string& map_path) {
    std::unique_ptr<MapDatabase> db;
    std::vector<RunInfo> runs;
    EXPECT_TRUE(MapDatabase::Open(map_path, OpenMode::kReadOnly, &db).ok());
    if (db) {
      EXPECT_TRUE(db->ListRuns(&runs).ok());
    }
    return runs;
  }

  static fs::path* dir_;
};

fs::path* RunPipelineTest::dir_ = nullptr;

TEST_F(RunPipelineTest, TheSummaryAccountsForEveryFrameAndMatchesTheMap) {
  const std::string map_path = MapPath("summary.db");
  RunSummary summary;
  ASSERT_EQ(app::Run(Request(Sequence(), map_path), &summary), kExitOk);
  EXPECT_EQ(summary.frames_read, kFrames);
  EXPECT_EQ(summary.frames_processed, kFrames);
  EXPECT_TRUE(summary.skipped.empty());
  EXPECT_FALSE(summary.interrupted);
  // Every processed frame but the first two (no pair yet) has a result: detected with some
  // status, or carried.
  const int detected =
      std::accumulate(summary.status_counts.begin(), summary.status_counts.end(), 0);
  EXPECT_EQ(detected + summary.frames_carried, kFrames - 2);
  EXPECT_GT(detected, kFrames / 3);
  EXPECT_NEAR(summary.distance_m, 1.3, 0.1);  // the scene drives 0.5 m/s at 15 frames/s
  EXPECT_GT(summary.keyframes, 2);
  EXPECT_EQ(summary.saved_keyframes, 0);
  ASSERT_EQ(static_cast<int>(summary.trajectory.size()), kFrames);
  ASSERT_TRUE(summary.extent_min_m && summary.extent_max_m);

  const std::vector<RunInfo> runs = RunsIn(map_path);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].status, RunStatus::kFinished);
  std::unique_ptr<MapDatabase> db;
  ASSERT_TRUE(MapDatabase::Open(map_path, OpenMode::kReadOnly, &db).ok());
  MapInfo info;
  ASSERT_TRUE(db->Info(&info).ok());
  EXPECT_EQ(info.frames, kFrames);
  EXPECT_EQ(info.keyframes, summary.keyframes - summary.keyframes_culled);
  ASSERT_TRUE(info.extent_min_m && info.extent_max_m);
  EXPECT_TRUE(info.extent_min_m->isApprox(*summary.extent_min_m));
  EXPECT_TRUE(info.extent_max_m->isApprox(*summary.extent_max_m));
  // The summary's trajectory is each frame's pose when it was added, stored as its raw pose.
  std::vector<TrajectoryPoint> trajectory;
  ASSERT_TRUE(db->ReadTrajectory(std::nullopt, PoseSource::kRaw, &trajectory).ok());
  ASSERT_EQ(trajectory.size(), summary.trajectory.size());
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const auto& [pose, stamp_ns] = summary.trajectory[i];
    EXPECT_EQ(trajectory[i].stamp_ns, stamp_ns) << i;
    EXPECT_NEAR(trajectory[i].map_from_base.x, pose.x, 1e-9) << i;
    EXPECT_NEAR(trajectory[i].map_from_base.y, pose.y, 1e-9) << i;
    EXPECT_NEAR(trajectory[i].map_from_base.yaw, pose.yaw, 1e-9) << i;
  }
}

// A run that ends between keyframes: its last detected frame (every 2nd one from frame 3 on)
// becomes a keyframe too, with its local map, so what the frames after the last regular keyframe
// saw is in the map. Here the regular keyframes are every 4th frame (3, 7, ..., 31, 35: the
// corners seen change fast), so 34 frames end after 31 and frame 33 is the last.
TEST_F(RunPipelineTest, TheFramesAfterTheLastKeyframeReachTheMap) {
  const std::string map_path = MapPath("tail.db");
  RunRequest request = Request(Sequence(), map_path);
  request.max_frames = 34;
  RunSummary summary;
  ASSERT_EQ(app::Run(request, &summary), kExitOk);
  std::unique_ptr<MapDatabase> db;
  ASSERT_TRUE(MapDatabase::Open(map_path, OpenMode::kReadOnly, &db).ok());
  std::vector<TrajectoryPoint> trajectory;
  ASSERT_TRUE(db->ReadTrajectory(std::nullopt, PoseSource::kRaw, &trajectory).ok());
  std::vector<std::int64_t> keyframes;
  for (const TrajectoryPoint& p : trajectory) {
    if (p.is_keyframe) keyframes.push_back(p.index);
  }
  ASSERT_GE(keyframes.size(), 2u);
  EXPECT_GE(keyframes.back(), 32);
  EXPECT_EQ(static_cast<int>(keyframes.size()), summary.keyframes - summary.keyframes_culled);
  OccupancyGrid local_map;
  EXPECT_TRUE(db->ReadLocalMap(trajectory.back().run_id, keyframes.back(), &local_map).ok());
  EXPECT_FALSE(local_map.cells.empty());
}

TEST_F(RunPipelineTest, AFrameThatIsNoImageIsSkippedByNameAndTheRunGoesOn) {
  RunSummary summary;
  ASSERT_EQ(app::Run(Request(Broken()), &summary), kExitOk);
  EXPECT_EQ(summary.frames_read, kFrames);
  EXPECT_EQ(summary.frames_processed, kFrames - 1);
  ASSERT_EQ(summary.skipped.size(), 1u);
  EXPECT_EQ(summary.skipped[0], Broken() + "/images/000010.png: cannot decode image");
  EXPECT_EQ(static_cast<int>(summary.trajectory.size()), kFrames - 1);
}

TEST_F(RunPipelineTest, MaxFramesStopsTheInput) {
  RunRequest request = Request(Sequence());
  request.max_frames = 12;
  RunSummary summary;
  ASSERT_EQ(app::Run(request, &summary), kExitOk);
  EXPECT_EQ(summary.frames_read, 12);
  EXPECT_EQ(summary.frames_processed, 12);
}

// The corridor's first frames see too little of the walls to localise in the saved grid: the run
// starts at the start pose, and its floor features close loops against the saved keyframes.
TEST_F(RunPipelineTest, ASecondRunExtendsTheMapAndClosesLoopsOnIt) {
  const std::string map_path = MapPath("extend.db");
  RunSummary first;
  ASSERT_EQ(app::Run(Request(Sequence(), map_path), &first), kExitOk);
  RunSummary second;
  ASSERT_EQ(app::Run(Request(Sequence(), map_path), &second), kExitOk);
  EXPECT_EQ(second.saved_keyframes, first.keyframes - first.keyframes_culled);
  EXPECT_EQ(second.localization.rfind("too few occupied points (", 0), 0u) << second.localization;
  EXPECT_GT(second.loop_closures_to_saved, 0);
  EXPECT_EQ(second.loop_closures_to_saved_floor, second.loop_closures_to_saved);
  const std::vector<RunInfo> runs = RunsIn(map_path);
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[1].status, RunStatus::kFinished);
}

TEST_F(RunPipelineTest, OneWriterPerMap) {
  const std::string map_path = MapPath("one_writer.db");
  const CameraCalibration calibration = sim::DefaultSimCalibration();
  RunSummary first_summary, second_summary;
  MapSink first(calibration, Request(Sequence(), map_path), true, &first_summary);
  std::string error;
  ASSERT_TRUE(first.Open(&error)) << error;
  // A second sink on the map the first one is writing is refused with the reason...
  MapSink second(calibration, Request(Sequence(), map_path), true, &second_summary);
  EXPECT_FALSE(second.Open(&error));
  EXPECT_NE(error.find("another process is writing this map"), std::string::npos) << error;
  // ... and so is a whole run, as bad input, leaving the map to the first.
  RunSummary run_summary;
  EXPECT_EQ(app::Run(Request(Sequence(), map_path), &run_summary), kExitBadInput);
  const ObstacleDetector detector(calibration, DetectorOptions());
  ASSERT_TRUE(first.Close(detector, &error)) << error;
  const std::vector<RunInfo> runs = RunsIn(map_path);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].status, RunStatus::kFinished);
}

}  // namespace
}  // namespace monoplane::app
