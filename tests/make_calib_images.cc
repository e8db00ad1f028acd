// make_calib_images OUT_DIR: simulator-rendered chessboard images for the CLI tests of
// `monoplane calibrate` (tests/CMakeLists.txt):
//   intrinsics/view_NN.png  twelve views for intrinsics, and intrinsics/zz_empty.png with no board
//   few/                    two views and one without a board (too few views)
//   mixed/                  five views and one at another resolution (not one camera)
//   floor.png               the mounted camera (true mount) sees the board on the floor
//   floor_higher.png        the board seen with the camera 8 cm higher (not the same floor)
//   board_pose.txt          X,Y,YAW_DEG of the board in floor.png, for --board-pose
//   true.yaml               the true calibration
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "tests/calibration_views.h"

int main(int argc, char** argv) {
  using namespace monoplane;
  using namespace monoplane::testing;
  if (argc != 2) {
    std::cerr << "usage: make_calib_images OUT_DIR\n";
    return 2;
  }
  const std::filesystem::path out(argv[1]);
  for (const char* sub : {"intrinsics", "few", "mixed"}) {
    std::filesystem::remove_all(out / sub);
    std::filesystem::create_directories(out / sub);
  }
  bool ok = true;
  auto write = [&](const std::filesystem::path& path, const cv::Mat& image) {
    ok = cv::imwrite(path.string(), image) && ok;
  };
  const std::vector<BoardView> views = RenderIntrinsicsViews();
  for (std::size_t i = 0; i < views.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "view_%02zu.png", i);
    write(out / "intrinsics" / name, views[i].image);
    if (i < 2) write(out / "few" / name, views[i].image);
    if (i < 5) write(out / "mixed" / name, views[i].image);
  }
  const cv::Mat1b empty = RenderEmptyFloor();
  write(out / "intrinsics" / "zz_empty.png", empty);
  write(out / "few" / "zz_empty.png", empty);
  cv::Mat1b smaller;
  cv::resize(views[5].image, smaller, cv::Size(320, 240), 0, 0, cv::INTER_AREA);
  write(out / "mixed" / "view_05_small.png", smaller);

  const CameraCalibration truth = TrueCalibration();
  const BoardView floor = RenderBoardView(truth.mount, {320, 330}, 0.2, 1000);
  write(out / "floor.png", floor.image);
  CameraMount higher = truth.mount;
  higher.height_m += 0.08;
  write(out / "floor_higher.png", RenderBoardView(higher, {320, 330}, 0.2, 1001).image);
  std::ofstream pose(out / "board_pose.txt");
  char line[96];
  std::snprintf(line, sizeof(line), "%.6f,%.6f,%.6f", floor.base_from_board.x,
                floor.base_from_board.y, floor.base_from_board.yaw * 180.0 / M_PI);
  pose << line;
  std::ofstream yaml(out / "true.yaml");
  yaml << CalibrationToYaml(truth);
  if (!ok || !pose.good() || !yaml.good()) {
    std::cerr << "make_calib_images: cannot write into " << out << "\n";
    return 1;
  }
  std::printf("wrote calibration images into %s\n", out.c_str());
  return 0;
}
