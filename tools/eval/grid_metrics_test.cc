#include "tools/eval/grid_metrics.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "tools/eval/eval_report.h"
#include "tools/eval/eval_test_fixtures.h"

namespace monoplane::eval {
namespace {

namespace fs = std::filesystem;

class GridMetricsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("monoplane_grid_test_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes NAME.yaml + NAME.pgm (map_server trinary, as INTERFACES.md exports them) and loads it.
  MapServerMap WriteAndLoad(const std::string& name, const cv::Mat& pgm, double resolution,
                            double origin_x, double origin_y, double free_thresh = 0.196) {
    const fs::path yaml = dir_ / (name + ".yaml");
    EXPECT_TRUE(cv::imwrite((dir_ / (name + ".pgm")).string(), pgm));
    std::ofstream(yaml) << "image: " << name << ".pgm\nmode: trinary\nresolution: " << resolution
                        << "\norigin: [" << origin_x << ", " << origin_y
                        << ", 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: " << free_thresh
                        << "\n";
    MapServerMap map;
    std::string error;
    EXPECT_TRUE(LoadMapServerMap(yaml.string(), &map, &error)) << error;
    return map;
  }

  // A 40x40 free map (image rows: top = highest y) with a vertical wall in column wall_col,
  // image rows 5..34.
  static cv::Mat WallImage(int wall_col) {
    cv::Mat image(40, 40, CV_8UC1, cv::Scalar(254));
    for (int r = 5; r < 35; ++r) image.at<std::uint8_t>(r, wall_col) = 0;
    return image;
  }

  fs::path dir_;
};

TEST_F(GridMetricsTest, ReaderHonoursOriginRowOrderAndTrinaryUnknown) {
  cv::Mat image(3, 4, CV_8UC1, cv::Scalar(254));
  image.at<std::uint8_t>(0, 1) = 0;    // top row: highest y
  image.at<std::uint8_t>(2, 3) = 205;  // bottom row: unknown with free_thresh 0.196
  const MapServerMap map = WriteAndLoad("m", image, 0.5, -1.0, 2.0);
  EXPECT_EQ(map.grid.geometry.width, 4);
  EXPECT_EQ(map.grid.geometry.height, 3);
  EXPECT_EQ(map.grid.At(1, 2), kCellOccupied);
  EXPECT_EQ(map.grid.At(3, 0), kCellUnknown);
  EXPECT_EQ(map.grid.At(0, 0), kCellFree);
  // Cell (1, 2) spans x in [-0.5, 0), y in [3.0, 3.5).
  EXPECT_EQ(map.ValueAt({-0.25, 3.25}), kCellOccupied);
  EXPECT_EQ(map.ValueAt({0.75, 2.25}), kCellUnknown);
  EXPECT_FALSE(map.ValueAt({-1.1, 2.1}).has_value());

  // map_server has no exception for the unknown shade: with free_thresh 0.25 (nav2's old saver
  // default) p = 50 / 255 = 0.196 < 0.25 loads as free, and so it is scored.
  const MapServerMap trap = WriteAndLoad("trap", image, 0.5, -1.0, 2.0, 0.25);
  EXPECT_EQ(trap.grid.At(3, 0), kCellFree);
  EXPECT_EQ(trap.grid.At(1, 2), kCellOccupied);
}

TEST_F(GridMetricsTest, NegatedImageAndMissingFilesAreHandled) {
  const fs::path yaml = dir_ / "neg.yaml";
  cv::Mat image(1, 3, CV_8UC1);
  image.at<std::uint8_t>(0, 0) = 0;
  image.at<std::uint8_t>(0, 1) = 255;
  image.at<std::uint8_t>(0, 2) = 128;
  ASSERT_TRUE(cv::imwrite((dir_ / "neg.pgm").string(), image));
  std::ofstream(yaml) << "image: neg.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\n"
                         "occupied_thresh: 0.65\nfree_thresh: 0.196\n";
  MapServerMap map;
  std::string error;
  ASSERT_TRUE(LoadMapServerMap(yaml.string(), &map, &error)) << error;
  EXPECT_EQ(map.grid.At(0, 0), kCellFree);      // negated: black is free
  EXPECT_EQ(map.grid.At(1, 0), kCellOccupied);  // white is occupied
  EXPECT_EQ(map.grid.At(2, 0), kCellUnknown);

  std::ofstream(dir_ / "bad.yaml") << "image: nothing.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n";
  EXPECT_FALSE(LoadMapServerMap((dir_ / "bad.yaml").string(), &map, &error));
  EXPECT_NE(error.find("nothing.pgm"), std::string::npos) << error;
  std::ofstream(dir_ / "bad2.yaml") << "image: neg.pgm\norigin: [0, 0, 0]\n";
  EXPECT_FALSE(LoadMapServerMap((dir_ / "bad2.yaml").string(), &map, &error));
  EXPECT_NE(error.find("resolution: missing"), std::string::npos) << error;
}

TEST_F(GridMetricsTest, PerfectPredictionScoresOne) {
  const MapServerMap gt = WriteAndLoad("gt", WallImage(10), 0.05, -1.0, -1.0);
  GridEvalResult r;
  std::string error;
  ASSERT_TRUE(CompareGrids(gt, gt, GridEvalOptions{}, {}, &r, &error)) << error;
  EXPECT_EQ(r.gt_occupied, 30);
  EXPECT_EQ(r.pred_occupied, 30);
  EXPECT_DOUBLE_EQ(*r.precision, 1.0);
  EXPECT_DOUBLE_EQ(*r.recall, 1.0);
  EXPECT_DOUBLE_EQ(*r.f1, 1.0);
  EXPECT_EQ(r.dangerous, 0);
  EXPECT_DOUBLE_EQ(*r.unknown_share, 0.0);
  EXPECT_EQ(r.gt_cells_scored, 1600);
}

TEST_F(GridMetricsTest, ShiftByKCellsScoresZeroBelowAndOneAtTolerance) {
  const int k = 3;
  const MapServerMap gt = WriteAndLoad("gt", WallImage(10), 0.05, -1.0, -1.0);
  const MapServerMap pred = WriteAndLoad("pred", WallImage(10 + k), 0.05, -1.0, -1.0);
  GridEvalResult r;
  std::string error;
  GridEvalOptions options;
  options.tolerance_cells = k - 1;
  ASSERT_TRUE(CompareGrids(pred, gt, options, {}, &r, &error)) << error;
  EXPECT_DOUBLE_EQ(*r.precision, 0.0);
  EXPECT_DOUBLE_EQ(*r.recall, 0.0);
  EXPECT_DOUBLE_EQ(*r.f1, 0.0);
  EXPECT_EQ(r.dangerous, 30);  // every wall cell is free in the prediction
  EXPECT_DOUBLE_EQ(*r.dangerous_share, 1.0);
  ASSERT_EQ(r.dangerous_cells_m.size(), 30u);  // where: the wall's column (10), in metres
  for (const Eigen::Vector2d& c : r.dangerous_cells_m) EXPECT_NEAR(c.x(), -1.0 + 10.5 * 0.05, 1e-9);

  options.tolerance_cells = k;
  ASSERT_TRUE(CompareGrids(pred, gt, options, {}, &r, &error)) << error;
  EXPECT_DOUBLE_EQ(*r.precision, 1.0);
  EXPECT_DOUBLE_EQ(*r.recall, 1.0);
  EXPECT_EQ(r.dangerous, 0);
}

TEST_F(GridMetricsTest, ComparesInMetresAcrossOriginsAndResolutions) {
  // The same world at half the cell size and an origin 0.5 m further left and down: the GT wall
  // cell column 10 covers x in [-0.5, -0.45); in the finer map that is columns 20, 21 + 20 =
  // 40, 41.
  const MapServerMap gt = WriteAndLoad("gt", WallImage(10), 0.05, -1.0, -1.0);
  cv::Mat fine(100, 100, CV_8UC1, cv::Scalar(254));
  // GT image rows 5..34 cover y in [-1 + (40-35)*0.05, -1 + (40-5)*0.05) = [-0.75, 0.75).
  // Fine map: origin y -1.5, 100 rows of 0.025: y in [-0.75, 0.75) = rows from bottom 30..89,
  // image rows 100-1-89 = 10 .. 100-1-30 = 69.
  for (int r = 10; r <= 69; ++r) {
    fine.at<std::uint8_t>(r, 40) = 0;
    fine.at<std::uint8_t>(r, 41) = 0;
  }
  const MapServerMap pred = WriteAndLoad("fine", fine, 0.025, -1.5, -1.5);
  GridEvalResult r;
  std::string error;
  ASSERT_TRUE(CompareGrids(pred, gt, GridEvalOptions{}, {}, &r, &error)) << error;
  EXPECT_DOUBLE_EQ(*r.precision, 1.0);
  EXPECT_DOUBLE_EQ(*r.recall, 1.0);
  EXPECT_DOUBLE_EQ(*r.unknown_share, 0.0);
}

TEST_F(GridMetricsTest, UnknownShareAndRadiusRestriction) {
  const MapServerMap gt = WriteAndLoad("gt", WallImage(10), 0.05, -1.0, -1.0);
  // Prediction: only the left half (columns 0..19) is known; the right half is unknown.
  cv::Mat half = WallImage(10);
  half(cv::Rect(20, 0, 20, 40)).setTo(205);
  const MapServerMap pred = WriteAndLoad("half", half, 0.05, -1.0, -1.0);
  GridEvalResult r;
  std::string error;
  ASSERT_TRUE(CompareGrids(pred, gt, GridEvalOptions{}, {}, &r, &error)) << error;
  EXPECT_DOUBLE_EQ(*r.unknown_share, 0.5);
  EXPECT_EQ(r.gt_known_pred_unknown, 800);

  // Only cells within 0.1 m of a point deep in the unknown half: all of them unknown.
  GridEvalOptions options;
  options.radius_m = 0.1;
  ASSERT_TRUE(CompareGrids(pred, gt, options, {Eigen::Vector2d(0.5, 0.0)}, &r, &error)) << error;
  EXPECT_GT(r.gt_cells_scored, 0);
  EXPECT_LT(r.gt_cells_scored, 30);
  EXPECT_DOUBLE_EQ(*r.unknown_share, 1.0);
  EXPECT_FALSE(r.recall.has_value());  // no GT wall there
}

// The floor the camera saw near the robot, and how much of it the prediction reads free.
TEST_F(GridMetricsTest, SeenFloorIsScoredForItsRecallAsFree) {
  // A camera 1 m up pitched 45 deg down: every pixel's ray meets the floor about 1 m ahead, at an
  // optical depth of sqrt(2) m. Frame 0 at (-0.925, 0.025) facing +x: the floor at x = 0.075 m,
  // cell (21, 20) of the 5 cm GT grid whose origin is (-1, -1).
  CameraCalibration calibration = TinyCalibration();
  calibration.mount.pitch_deg = 45.0;
  const MapServerMap gt = WriteAndLoad("gt", WallImage(10), 0.05, -1.0, -1.0);
  const fs::path seq = dir_ / "floor_seq";
  fs::create_directories(seq / "gt" / "depth");
  std::ofstream(seq / "calib.yaml") << CalibrationToYaml(calibration);
  std::ofstream(seq / "gt" / "trajectory.txt") << "0.0 -0.925 0.025 0 0 0 0 1\n";
  ASSERT_TRUE(cv::imwrite((seq / "gt/depth/000000.png").string(),
                          cv::Mat(3, 4, CV_16UC1, cv::Scalar(1414))));
  std::vector<std::uint8_t> floor, surface;
  std::string error;
  ASSERT_TRUE(SeenFloorCells(seq.string(), gt, 1, 0.01, 4.0, &floor, &error)) << error;
  const GridGeometry& g = gt.grid.geometry;
  ASSERT_EQ(floor.size(), g.NumCells());
  EXPECT_EQ(std::count(floor.begin(), floor.end(), 1), 1);
  EXPECT_EQ(floor[g.Index(21, 20)], 1);
  // Not a surface above the floor; and beyond --free-range nothing is scored.
  ASSERT_TRUE(SeenSurfaceCells(seq.string(), gt, 1, 0.03, 6.0, &surface, &error)) << error;
  EXPECT_EQ(std::count(surface.begin(), surface.end(), 1), 0);
  std::vector<std::uint8_t> far;
  ASSERT_TRUE(SeenFloorCells(seq.string(), gt, 1, 0.01, 0.5, &far, &error)) << error;
  EXPECT_EQ(std::count(far.begin(), far.end(), 1), 0);

  // A prediction that knows the wall but leaves that floor unknown, and one that knows it free.
  cv::Mat unknown_floor = WallImage(10);
  unknown_floor.at<std::uint8_t>(39 - 20, 21) = 205;
  GridEvalResult r;
  ASSERT_TRUE(CompareGrids(WriteAndLoad("unknown_floor", unknown_floor, 0.05, -1.0, -1.0), gt,
                           GridEvalOptions{}, {}, &r, &error, nullptr, &floor))
      << error;
  EXPECT_TRUE(r.free_seen_scored);
  EXPECT_EQ(r.gt_free_seen, 1);
  EXPECT_EQ(r.gt_free_seen_free, 0);
  EXPECT_DOUBLE_EQ(*r.free_recall_seen, 0.0);
  ASSERT_TRUE(CompareGrids(gt, gt, GridEvalOptions{}, {}, &r, &error, nullptr, &floor)) << error;
  EXPECT_DOUBLE_EQ(*r.free_recall_seen, 1.0);
  ASSERT_TRUE(CompareGrids(gt, gt, GridEvalOptions{}, {}, &r, &error)) << error;
  EXPECT_FALSE(r.free_seen_scored);
  const std::vector<std::uint8_t> wrong_size(7, 0);
  EXPECT_FALSE(CompareGrids(gt, gt, GridEvalOptions{}, {}, &r, &error, nullptr, &wrong_size));
}

TEST_F(GridMetricsTest, SeenCellsComeFromGroundTruthDepthAtTheTrajectory) {
  // The tiny level camera 1 m up sees every pixel's point (within a millimetre) d metres ahead
  // at 1 m height. Frame 0 at (-1, 0.025) facing +x with d = 0.525 m and frame 1 at (0, 0.525)
  // facing -x with d = 0.475 m both see x = -0.475: the wall's cells (10, 20) and (10, 30).
  const MapServerMap gt = WriteAndLoad("gt", WallImage(10), 0.05, -1.0, -1.0);
  const fs::path seq = dir_ / "seq";
  fs::create_directories(seq / "gt" / "depth");
  std::ofstream(seq / "calib.yaml") << CalibrationToYaml(TinyCalibration());
  std::ofstream(seq / "gt" / "trajectory.txt") << "0.0 -1 0.025 0 0 0 0 1\n0.1 0 0.525 0 0 0 1 0\n";
  ASSERT_TRUE(cv::imwrite((seq / "gt/depth/000000.png").string(),
                          cv::Mat(3, 4, CV_16UC1, cv::Scalar(525))));
  ASSERT_TRUE(cv::imwrite((seq / "gt/depth/000001.png").string(),
                          cv::Mat(3, 4, CV_16UC1, cv::Scalar(475))));
  std::vector<std::uint8_t> seen;
  std::string error;
  ASSERT_TRUE(SeenSurfaceCells(seq.string(), gt, 1, 0.03, 6.0, &seen, &error)) << error;
  const GridGeometry& g = gt.grid.geometry;
  ASSERT_EQ(seen.size(), g.NumCells());
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), 2);
  EXPECT_EQ(seen[g.Index(10, 20)], 1);
  EXPECT_EQ(seen[g.Index(10, 30)], 1);

  // A prediction with the wall's cell (10, 20) alone: of the two seen GT cells one is recalled;
  // with a tolerance of 1 cell the seen ones are (10, 19..21) and (10, 29..31), 3 recalled.
  cv::Mat one(40, 40, CV_8UC1, cv::Scalar(254));
  one.at<std::uint8_t>(39 - 20, 10) = 0;
  const MapServerMap pred = WriteAndLoad("one", one, 0.05, -1.0, -1.0);
  GridEvalResult r;
  ASSERT_TRUE(CompareGrids(pred, gt, GridEvalOptions{}, {}, &r, &error, &seen)) << error;
  EXPECT_TRUE(r.seen_scored);
  EXPECT_EQ(r.gt_occupied_seen, 2);
  EXPECT_EQ(r.gt_occupied_seen_recalled, 1);
  EXPECT_DOUBLE_EQ(*r.recall_seen, 0.5);
  EXPECT_DOUBLE_EQ(*r.f1_seen, 2.0 * 1.0 * 0.5 / 1.5);
  GridEvalOptions tolerant;
  tolerant.tolerance_cells = 1;
  ASSERT_TRUE(CompareGrids(pred, gt, tolerant, {}, &r, &error, &seen)) << error;
  EXPECT_EQ(r.gt_occupied_seen, 6);
  EXPECT_EQ(r.gt_occupied_seen_recalled, 3);
  ASSERT_TRUE(CompareGrids(pred, gt, tolerant, {}, &r, &error)) << error;
  EXPECT_FALSE(r.seen_scored);  // not asked for
  EXPECT_FALSE(r.recall_seen.has_value());

  // Points below min_height_m are not surfaces, nor those beyond max_range_m (0.525 m and 0.475 m
  // ahead here); a frame without a pose is an error.
  ASSERT_TRUE(SeenSurfaceCells(seq.string(), gt, 1, 1.5, 6.0, &seen, &error)) << error;
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), 0);
  ASSERT_TRUE(SeenSurfaceCells(seq.string(), gt, 1, 0.03, 0.5, &seen, &error)) << error;
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), 1);
  EXPECT_EQ(seen[g.Index(10, 30)], 1);
  ASSERT_TRUE(cv::imwrite((seq / "gt/depth/000002.png").string(),
                          cv::Mat(3, 4, CV_16UC1, cv::Scalar(500))));
  EXPECT_FALSE(SeenSurfaceCells(seq.string(), gt, 1, 0.03, 6.0, &seen, &error));
  EXPECT_NE(error.find("000002.png"), std::string::npos) << error;
  EXPECT_FALSE(SeenSurfaceCells(seq.string(), gt, 1, 0.03, -1.0, &seen, &error));
  EXPECT_NE(error.find("must be > 0"), std::string::npos) << error;
  const std::vector<std::uint8_t> wrong_size(7, 0);
  EXPECT_FALSE(CompareGrids(pred, gt, tolerant, {}, &r, &error, &wrong_size));
}

// The GT-free cells under a mover's footprint, and those the prediction keeps occupied; GT
// obstacles under a footprint are not part of the path.
TEST_F(GridMetricsTest, MoverPathCellsReadOccupiedAreCounted) {
  // GT: 40 x 40 cells of 0.1 m, origin (0, 0), a wall in column 30 (x 3.0-3.1 m).
  const MapServerMap gt = WriteAndLoad("gt", WallImage(30), 0.1, 0.0, 0.0);
  // Prediction: the wall, and an obstacle left where the mover walked (x 1.0-1.1 m, y 2.0-2.1 m).
  cv::Mat pred_image = WallImage(30);
  pred_image.at<std::uint8_t>(40 - 1 - 20, 10) = 0;
  const MapServerMap pred = WriteAndLoad("pred", pred_image, 0.1, 0.0, 0.0);
  // A mover of radius 0.08 m walking along y = 2.05 from x = 0.55 to 3.05 (into the wall).
  std::vector<std::pair<Eigen::Vector2d, double>> footprints;
  for (int k = 0; k <= 25; ++k)
    footprints.emplace_back(Eigen::Vector2d(0.55 + 0.1 * k, 2.05), 0.08);
  GridEvalResult result;
  MoverPathOccupancy(pred, gt, footprints, &result);
  EXPECT_TRUE(result.mover_path_scored);
  // Columns 5..30 of row 20, less the wall's cell (GT occupied), plus nothing else: the disc of
  // 0.08 m around a cell centre covers only that cell.
  EXPECT_EQ(result.mover_path_cells, 25);
  EXPECT_EQ(result.mover_path_occupied, 1);
  const std::string json = GridReportJson(result);
  EXPECT_NE(json.find("\"mover_path_occupied\": 1"), std::string::npos) << json;
}

TEST_F(GridMetricsTest, InvalidOptionsAreRejected) {
  const MapServerMap gt = WriteAndLoad("gt", WallImage(10), 0.05, 0.0, 0.0);
  GridEvalOptions options;
  options.tolerance_cells = -1;
  GridEvalResult r;
  std::string error;
  EXPECT_FALSE(CompareGrids(gt, gt, options, {}, &r, &error));
  EXPECT_NE(error.find("tolerance_cells"), std::string::npos);
}

}  // namespace
}  // namespace monoplane::eval
