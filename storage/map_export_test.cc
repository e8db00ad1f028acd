#include "storage/map_export.h"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "storage/test_util.h"

namespace monoplane {
namespace {

using testing::MarkCell;
using testing::TempDir;

// An independent reader of binary PGM (P5, maxval 255, '#' comments allowed in the header).
struct Pgm {
  int width = 0, height = 0;
  std::vector<unsigned char> pixels;  // row-major, top row first
  unsigned char At(int col, int row_from_top) const {
    return pixels[static_cast<std::size_t>(row_from_top) * width + col];
  }
};

bool ReadPgm(const std::string& path, Pgm* pgm) {
  const std::string bytes = testing::ReadFileBytes(path);
  std::size_t pos = 0;
  auto next_token = [&]() {
    while (pos < bytes.size()) {
      if (bytes[pos] == '#') {
        while (pos < bytes.size() && bytes[pos] != '\n') ++pos;
      } else if (std::isspace(static_cast<unsigned char>(bytes[pos]))) {
        ++pos;
      } else {
        break;
      }
    }
    const std::size_t start = pos;
    while (pos < bytes.size() && !std::isspace(static_cast<unsigned char>(bytes[pos]))) ++pos;
    return bytes.substr(start, pos - start);
  };
  if (next_token() != "P5") return false;
  pgm->width = std::stoi(next_token());
  pgm->height = std::stoi(next_token());
  if (next_token() != "255") return false;
  ++pos;  // the single whitespace after maxval
  const std::size_t n = static_cast<std::size_t>(pgm->width) * pgm->height;
  if (bytes.size() - pos != n) return false;
  pgm->pixels.assign(bytes.begin() + static_cast<std::ptrdiff_t>(pos), bytes.end());
  return true;
}

// A map at 0.1 m with cells from x = -1.0 to 0.9 and y = -0.5 to 1.4: an occupied cell high
// up-left, a free cell low right, an unknown (observed, p = 0.5) cell and never-seen cells.
TiledGrid TestGrid() {
  TiledGrid grid(0.1);
  MarkCell(&grid, grid.CellOf({-1.0 + 0.05, -0.5 + 0.05}), -2.0f);  // lower-left corner: free
  MarkCell(&grid, grid.CellOf({0.9 + 0.05, 1.4 + 0.05}), -2.0f);    // upper-right corner: free
  MarkCell(&grid, grid.CellOf({-0.75, 1.25}), 2.0f, 0.3f);          // occupied, high y, left
  MarkCell(&grid, grid.CellOf({0.55, -0.25}), -2.0f);               // free, low y, right
  MarkCell(&grid, grid.CellOf({0.15, 0.15}), 0.0f);                 // observed but p = 0.5
  return grid;
}

TEST(MapExport, MapServerYamlAndPgmReadBackIndependently) {
  TempDir dir;
  const OccupancyGrid grid = ToOccupancyGrid(TestGrid());
  ASSERT_EQ(grid.geometry.width, 20);
  ASSERT_EQ(grid.geometry.height, 20);
  std::string error;
  const std::string yaml_path = dir.File("map.yaml");
  ASSERT_TRUE(WriteMapServerFiles(grid, yaml_path, &error)) << error;
  EXPECT_EQ(MapServerImagePath(yaml_path), dir.File("map.pgm"));

  const YAML::Node yaml = YAML::LoadFile(yaml_path);
  EXPECT_EQ(yaml["image"].as<std::string>(), "map.pgm");
  EXPECT_EQ(yaml["mode"].as<std::string>(), "trinary");
  EXPECT_DOUBLE_EQ(yaml["resolution"].as<double>(), 0.1);
  ASSERT_EQ(yaml["origin"].size(), 3u);
  EXPECT_NEAR(yaml["origin"][0].as<double>(), -1.0, 1e-9);
  EXPECT_NEAR(yaml["origin"][1].as<double>(), -0.5, 1e-9);
  EXPECT_EQ(yaml["origin"][2].as<double>(), 0.0);
  EXPECT_EQ(yaml["negate"].as<int>(), 0);
  EXPECT_DOUBLE_EQ(yaml["occupied_thresh"].as<double>(), 0.65);
  EXPECT_DOUBLE_EQ(yaml["free_thresh"].as<double>(), 0.196);

  Pgm pgm;
  ASSERT_TRUE(ReadPgm(dir.File("map.pgm"), &pgm));
  ASSERT_EQ(pgm.width, 20);
  ASSERT_EQ(pgm.height, 20);
  // map_server's rule: pixel (col, row from top) covers x = origin_x + col * res and
  // y = origin_y + (height - 1 - row) * res.
  auto pixel_at = [&](double x, double y) {
    const int col = static_cast<int>(std::floor((x - (-1.0)) / 0.1));
    const int row = pgm.height - 1 - static_cast<int>(std::floor((y - (-0.5)) / 0.1));
    return pgm.At(col, row);
  };
  EXPECT_EQ(pixel_at(-0.75, 1.25), 0);    // occupied, near the top
  EXPECT_EQ(pgm.At(2, 2), 0);             // the same cell by raw index: top rows = high y
  EXPECT_EQ(pixel_at(0.55, -0.25), 254);  // free
  EXPECT_EQ(pixel_at(0.15, 0.15), 205);   // observed, p = 0.5: unknown
  EXPECT_EQ(pixel_at(0.0, 0.5), 205);     // never seen
  EXPECT_EQ(pgm.At(0, 19), 254);          // lower-left corner cell
  EXPECT_EQ(pgm.At(19, 0), 254);          // upper-right corner cell
  int counts[256] = {};
  for (unsigned char p : pgm.pixels) ++counts[p];
  EXPECT_EQ(counts[0], 1);
  EXPECT_EQ(counts[254], 3);
  EXPECT_EQ(counts[205], 400 - 4);

  // Nothing to export: a clear error naming the file.
  EXPECT_FALSE(WriteMapServerFiles(OccupancyGrid(), dir.File("empty.yaml"), &error));
  EXPECT_EQ(error.rfind(dir.File("empty.yaml"), 0), 0u) << error;
  EXPECT_FALSE(WriteMapServerFiles(grid, dir.File("no/such/dir/map.yaml"), &error));
  EXPECT_NE(error.find("no/such/dir/map.pgm"), std::string::npos) << error;
}

// nav2's map_io (and ROS 1's map_server) in trinary mode: p = (255 - v) / 255 with the YAML's own
// thresholds, occupied above occupied_thresh, free below free_thresh, otherwise unknown.
std::int8_t MapServerCell(unsigned char v, double occupied_thresh, double free_thresh) {
  const double p = (255.0 - v) / 255.0;
  if (p > occupied_thresh) return kCellOccupied;
  if (p < free_thresh) return kCellFree;
  return kCellUnknown;
}

TEST(MapExport, MapServerLoadsExactlyTheMapsCells) {
  TempDir dir;
  // Every state, also cells observed without a decision (p = 0.5) and never-observed ones.
  TiledGrid tiled = TestGrid();
  for (int i = 0; i < 12; ++i) {
    MarkCell(&tiled, tiled.CellOf({-0.95 + 0.1 * i, 0.35}), i % 3 == 0 ? 2.0f : -2.0f);
    MarkCell(&tiled, tiled.CellOf({-0.95 + 0.1 * i, 0.65}), i % 2 == 0 ? 0.1f : -0.1f);
  }
  const OccupancyGrid grid = ToOccupancyGrid(tiled);
  int counts[3] = {};
  for (std::int8_t c : grid.cells) ++counts[c == kCellUnknown ? 0 : c == kCellFree ? 1 : 2];
  ASSERT_GT(counts[0], 0);
  ASSERT_GT(counts[1], 0);
  ASSERT_GT(counts[2], 0);

  std::string error;
  const std::string yaml_path = dir.File("map.yaml");
  ASSERT_TRUE(WriteMapServerFiles(grid, yaml_path, &error)) << error;
  const YAML::Node yaml = YAML::LoadFile(yaml_path);
  const double occupied_thresh = yaml["occupied_thresh"].as<double>();
  const double free_thresh = yaml["free_thresh"].as<double>();
  Pgm pgm;
  ASSERT_TRUE(ReadPgm(dir.File("map.pgm"), &pgm));
  ASSERT_EQ(pgm.width, grid.geometry.width);
  ASSERT_EQ(pgm.height, grid.geometry.height);
  for (int row = 0; row < grid.geometry.height; ++row) {
    for (int col = 0; col < grid.geometry.width; ++col) {
      const unsigned char v = pgm.At(col, grid.geometry.height - 1 - row);
      EXPECT_EQ(MapServerCell(v, occupied_thresh, free_thresh), grid.At(col, row))
          << "cell " << col << ", " << row << " shade " << int(v);
    }
  }
  // The trap this guards against: with nav2's old default free_thresh 0.25 the unknown shade
  // loads as free.
  EXPECT_EQ(MapServerCell(205, 0.65, 0.25), kCellFree);
  EXPECT_EQ(MapServerCell(205, occupied_thresh, free_thresh), kCellUnknown);
}

TEST(MapExport, TumTrajectory) {
  TempDir dir;
  std::vector<TrajectoryPoint> trajectory(3);
  trajectory[0].stamp_ns = 1700000000123456789ll;
  trajectory[0].map_from_base = {1.5, -2.25, 0.0};
  trajectory[1].stamp_ns = 1700000000223456789ll;
  trajectory[1].map_from_base = {1.6, -2.2, M_PI / 2.0};
  trajectory[2].stamp_ns = 5;
  trajectory[2].map_from_base = {0.0, 0.0, -3.0};
  std::string error;
  ASSERT_TRUE(WriteTumTrajectory(trajectory, dir.File("traj.txt"), &error)) << error;
  std::ifstream in(dir.File("traj.txt"));
  std::string line;
  std::vector<std::vector<double>> rows;
  std::vector<std::string> stamps;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string stamp;
    fields >> stamp;
    stamps.push_back(stamp);
    std::vector<double> v(7);
    for (double& x : v) fields >> x;
    ASSERT_TRUE(fields) << line;
    rows.push_back(v);
  }
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(stamps[0], "1700000000.123456789");
  EXPECT_EQ(stamps[2], "0.000000005");
  EXPECT_DOUBLE_EQ(rows[0][0], 1.5);
  EXPECT_DOUBLE_EQ(rows[0][1], -2.25);
  for (const auto& r : rows) {
    EXPECT_EQ(r[2], 0.0);  // z
    EXPECT_EQ(r[3], 0.0);  // qx
    EXPECT_EQ(r[4], 0.0);  // qy
    EXPECT_NEAR(r[5] * r[5] + r[6] * r[6], 1.0, 1e-8);
  }
  EXPECT_NEAR(2.0 * std::atan2(rows[1][5], rows[1][6]), M_PI / 2.0, 1e-8);
  EXPECT_NEAR(2.0 * std::atan2(rows[2][5], rows[2][6]), -3.0, 1e-8);
}

TEST(MapExport, MovingObjectsCsv) {
  TempDir dir;
  std::vector<MovingObjectObservation> observations(2);
  observations[0] = {1, 10, 1700000000123456789ll, 4, {2.5, -1.25}, {0.5, 1.0}, 0.3, false};
  observations[1] = {2, 3, 5, 1, {0.0, 0.0}, {0.0, 0.0}, 0.25, true};
  std::string error;
  ASSERT_TRUE(WriteMovingObjectsCsv(observations, dir.File("moving.csv"), &error)) << error;
  std::ifstream in(dir.File("moving.csv"));
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(),
            "stamp_s,run,frame,id,x_m,y_m,vx_mps,vy_mps,radius_m,coasting\n"
            "1700000000.123456789,1,10,4,2.5000,-1.2500,0.5000,1.0000,0.3000,0\n"
            "0.000000005,2,3,1,0.0000,0.0000,0.0000,0.0000,0.2500,1\n");
  EXPECT_FALSE(WriteMovingObjectsCsv(observations, dir.File("no_dir/moving.csv"), &error));
  EXPECT_NE(error.find("no_dir/moving.csv"), std::string::npos) << error;
}

TEST(MapExport, OctomapBytesRoundTripThroughTheDatabaseIntoABtFileOctomapReads) {
  TempDir dir;
  octomap::OcTree tree(0.05);
  tree.updateNode(octomap::point3d(1.0f, 2.0f, 0.3f), true);
  tree.updateNode(octomap::point3d(1.02f, 2.0f, 0.3f), true);
  tree.updateNode(octomap::point3d(-0.5f, 0.2f, 0.1f), false);
  tree.updateInnerOccupancy();
  std::ostringstream bytes;
  ASSERT_TRUE(tree.writeBinary(bytes));

  std::unique_ptr<MapDatabase> db;
  ASSERT_TRUE(MapDatabase::Open(dir.File("map.db"), OpenMode::kCreate, &db).ok());
  std::int64_t run = 0;
  ASSERT_TRUE(db->BeginRun(testing::TestCalibration(), "", "t", 0, &run).ok());
  ASSERT_TRUE(db->WriteOctomap(run, 0.05, bytes.str()).ok());
  StoredOctomap stored;
  ASSERT_TRUE(db->ReadOctomap(&stored).ok());
  std::string error;
  ASSERT_TRUE(WriteBytesFile(stored.bytes, dir.File("map.bt"), &error)) << error;

  octomap::OcTree back(0.1);
  ASSERT_TRUE(back.readBinary(dir.File("map.bt")));
  EXPECT_DOUBLE_EQ(back.getResolution(), 0.05);
  EXPECT_EQ(back.getNumLeafNodes(), tree.getNumLeafNodes());
  const octomap::OcTreeNode* occupied = back.search(1.0, 2.0, 0.3);
  ASSERT_NE(occupied, nullptr);
  EXPECT_TRUE(back.isNodeOccupied(occupied));
  const octomap::OcTreeNode* free_node = back.search(-0.5, 0.2, 0.1);
  ASSERT_NE(free_node, nullptr);
  EXPECT_FALSE(back.isNodeOccupied(free_node));
  EXPECT_EQ(back.search(5.0, 5.0, 5.0), nullptr);
}

TEST(MapExport, PictureShowsMapTopUpAndTheTrajectory) {
  TempDir dir;
  const OccupancyGrid grid = ToOccupancyGrid(TestGrid());
  std::vector<TrajectoryPoint> trajectory(2);
  trajectory[0].run_id = 1;
  trajectory[0].map_from_base = {-0.45, 0.95, 0.0};
  trajectory[1].run_id = 1;
  trajectory[1].map_from_base = {0.45, 0.95, 0.0};
  MapPictureOptions options;
  options.pixels_per_cell = 4;
  std::string error;
  ASSERT_TRUE(WriteMapPicture(grid, trajectory, options, dir.File("map.png"), &error)) << error;
  const cv::Mat picture = cv::imread(dir.File("map.png"), cv::IMREAD_COLOR);
  ASSERT_EQ(picture.cols, 80);
  ASSERT_EQ(picture.rows, 80);
  // The occupied cell (col 2, row from top 2) is black; the free one (col 15, row 17) white;
  // never-seen cells grey.
  EXPECT_EQ(picture.at<cv::Vec3b>(2 * 4 + 2, 2 * 4 + 2), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(picture.at<cv::Vec3b>(17 * 4 + 2, 15 * 4 + 2), cv::Vec3b(255, 255, 255));
  EXPECT_EQ(picture.at<cv::Vec3b>(79 - 40, 41), cv::Vec3b(160, 160, 160));
  // The metre grid: x = 0 m is column 40 (origin -1 m, 40 px per metre), a shade darker.
  EXPECT_EQ(picture.at<cv::Vec3b>(79 - 40, 40), cv::Vec3b(140, 140, 140));
  // The trajectory at y = 0.95 (0.55 m below the top edge at y = 1.5: 22 px), drawn in colour.
  const cv::Vec3b on_path = picture.at<cv::Vec3b>(22, 40);
  EXPECT_FALSE(on_path[0] == on_path[1] && on_path[1] == on_path[2]) << on_path;
  EXPECT_FALSE(WriteMapPicture(OccupancyGrid(), trajectory, options, dir.File("e.png"), &error));
  EXPECT_EQ(error.rfind(dir.File("e.png"), 0), 0u) << error;
}

TEST(MapExport, PictureHasAScaleBarWhenLargeEnough) {
  // 4 m x 3 m of free cells at 5 cm, 2 px per cell: 40 px per metre, 160 px wide, so a 1 m bar
  // (a quarter of the width) fits in the lower left corner; the 2 m one would not.
  OccupancyGrid grid(GridGeometry{0.05, 0.0, 0.0, 80, 60}, kCellFree);
  MapPictureOptions options;
  options.pixels_per_cell = 2;
  const cv::Mat picture = RenderMapPicture(grid, {}, options);
  ASSERT_EQ(picture.cols, 160);
  ASSERT_EQ(picture.rows, 120);
  const auto black = [&](int row, int col) {
    return picture.at<cv::Vec3b>(row, col) == cv::Vec3b(0, 0, 0);
  };
  // The bar: rows 110-112, columns 8-48 (1 m), nothing black past it on its rows.
  EXPECT_TRUE(black(111, 8));
  EXPECT_TRUE(black(111, 47));
  EXPECT_FALSE(black(111, 60));
  EXPECT_FALSE(black(111, 100));
  // Away from the bar and the grid lines the free floor is white.
  EXPECT_EQ(picture.at<cv::Vec3b>(30, 100), cv::Vec3b(255, 255, 255));
  // Too small a picture for a 1 m bar (a quarter of 40 px is 10 px): none.
  OccupancyGrid small(GridGeometry{0.05, 0.0, 0.0, 20, 40}, kCellFree);
  const cv::Mat no_bar = RenderMapPicture(small, {}, options);
  for (int row = 0; row < no_bar.rows; ++row) {
    for (int col = 0; col < no_bar.cols; ++col)
      ASSERT_NE(no_bar.at<cv::Vec3b>(row, col), cv::Vec3b(0, 0, 0)) << row << " " << col;
  }
}

}  // namespace
}  // namespace monoplane
