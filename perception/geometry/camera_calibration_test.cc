#include "perception/geometry/camera_calibration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <vector>

namespace monoplane {
namespace {

const std::string kCalibDir = std::string(MONOPLANE_SOURCE_DIR) + "/tests/data/calib";

TEST(CameraCalibration, LoadsTheInterfacesExample) {
  CameraCalibration c;
  std::string error;
  ASSERT_TRUE(LoadCalibrationFile(kCalibDir + "/default.yaml", &c, &error)) << error;
  EXPECT_EQ(c.intrinsics.width, 640);
  EXPECT_EQ(c.intrinsics.height, 480);
  EXPECT_DOUBLE_EQ(c.intrinsics.fx, 457.0);
  EXPECT_DOUBLE_EQ(c.intrinsics.cy, 239.5);
  EXPECT_DOUBLE_EQ(c.mount.x_m, 0.10);
  EXPECT_DOUBLE_EQ(c.mount.height_m, 0.40);
  EXPECT_DOUBLE_EQ(c.mount.pitch_deg, 22.0);
  EXPECT_FALSE(c.intrinsics.HasDistortion());
}

TEST(CameraCalibration, RoundTripsThroughYaml) {
  CameraCalibration c;
  c.intrinsics = {800, 600, 512.25, 511.5, 401.0, 300.25, {0.1, -0.05, 0.001, -0.002, 0.01}};
  c.mount = {0.2, -0.05, 0.35, 17.5, 1.25, -3.0};
  CameraCalibration back;
  std::string error;
  ASSERT_TRUE(ParseCalibrationYaml(CalibrationToYaml(c), &back, &error)) << error;
  EXPECT_EQ(back.intrinsics.width, 800);
  EXPECT_DOUBLE_EQ(back.intrinsics.fy, 511.5);
  EXPECT_DOUBLE_EQ(back.intrinsics.distortion[4], 0.01);
  EXPECT_DOUBLE_EQ(back.mount.y_m, -0.05);
  EXPECT_DOUBLE_EQ(back.mount.roll_deg, 1.25);
  EXPECT_DOUBLE_EQ(back.mount.yaw_deg, -3.0);
}

TEST(CameraCalibration, BaseFromCameraFollowsRep103) {
  CameraCalibration c;
  c.mount = {0.1, 0.0, 0.4, 0.0, 0.0, 0.0};
  Eigen::Isometry3d t = c.BaseFromCamera();
  // Level camera: optical z is base x, optical x is base -y, optical y is base -z.
  EXPECT_TRUE(t.linear().col(2).isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(t.linear().col(0).isApprox(-Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(t.linear().col(1).isApprox(-Eigen::Vector3d::UnitZ()));
  // Pitch down by 30 deg: the optical axis points forward and down.
  c.mount.pitch_deg = 30.0;
  t = c.BaseFromCamera();
  EXPECT_NEAR(t.linear().col(2).z(), -0.5, 1e-12);
  EXPECT_GT(t.linear().col(2).x(), 0.0);
  // Yaw left by 90 deg: the optical axis points along +y.
  c.mount.pitch_deg = 0.0;
  c.mount.yaw_deg = 90.0;
  EXPECT_TRUE(c.BaseFromCamera().linear().col(2).isApprox(Eigen::Vector3d::UnitY()));
  // Roll positive: the camera's right side (optical +x) dips toward the floor.
  c.mount.yaw_deg = 0.0;
  c.mount.roll_deg = 10.0;
  EXPECT_LT(c.BaseFromCamera().linear().col(0).z(), 0.0);
  EXPECT_NEAR(c.BaseFromCamera().translation().z(), 0.4, 1e-15);
}

TEST(CameraCalibration, ReadsRosCameraSectionAndIntrinsicsFiles) {
  const std::string ros =
      "image_width: 640\nimage_height: 480\ncamera_name: narrow_stereo\n"
      "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [450.5, 0, 320.1, 0, 451.5, 241.2, 0, 0, 1]\n"
      "distortion_model: plumb_bob\n"
      "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.1, 0.02, 0.001, 0.0, 0.0]\n"
      "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
      "projection_matrix:\n  rows: 3\n  cols: 4\n  data: [450, 0, 320, 0, 0, 451, 241, 0, 0, 0, 1, "
      "0]\n";
  const auto dir = std::filesystem::temp_directory_path() / "monoplane_calib_test";
  std::filesystem::create_directories(dir);
  { std::ofstream(dir / "ost.yaml") << ros; }
  CameraIntrinsics in;
  std::string error;
  ASSERT_TRUE(LoadIntrinsicsFile((dir / "ost.yaml").string(), &in, &error)) << error;
  EXPECT_DOUBLE_EQ(in.fx, 450.5);
  EXPECT_DOUBLE_EQ(in.cy, 241.2);
  EXPECT_DOUBLE_EQ(in.distortion[0], -0.1);

  // The same section embedded in a monoplane file as camera:.
  std::string embedded = "camera:\n";
  std::istringstream lines(ros);
  for (std::string line; std::getline(lines, line);) embedded += "  " + line + "\n";
  embedded += "mount: {x: 0, y: 0, height: 0.3, pitch_deg: 10, roll_deg: 0, yaw_deg: 0}\n";
  CameraCalibration c;
  ASSERT_TRUE(ParseCalibrationYaml(embedded, &c, &error)) << error;
  EXPECT_DOUBLE_EQ(c.intrinsics.fy, 451.5);
  EXPECT_EQ(c.intrinsics.height, 480);

  // What OpenCV's calibration sample writes: cv::FileStorage YAML with !!opencv-matrix.
  {
    cv::FileStorage fs((dir / "out_camera_data.yml").string(), cv::FileStorage::WRITE);
    fs << "image_width" << 1280 << "image_height" << 720;
    fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << 900, 0, 640.5, 0, 901, 360.5, 0, 0, 1);
    fs << "distortion_coefficients" << (cv::Mat_<double>(5, 1) << 0.05, -0.1, 0, 0, 0.02);
    fs << "avg_reprojection_error" << 0.2;
  }
  ASSERT_TRUE(LoadIntrinsicsFile((dir / "out_camera_data.yml").string(), &in, &error)) << error;
  EXPECT_EQ(in.width, 1280);
  EXPECT_DOUBLE_EQ(in.fy, 901.0);
  EXPECT_DOUBLE_EQ(in.cx, 640.5);
  EXPECT_DOUBLE_EQ(in.distortion[4], 0.02);
  // And monoplane's own file.
  ASSERT_TRUE(LoadIntrinsicsFile(kCalibDir + "/default.yaml", &in, &error)) << error;
  EXPECT_DOUBLE_EQ(in.fx, 457.0);
}

TEST(CameraCalibration, ScaledIntrinsicsKeepPixelCentres) {
  CameraIntrinsics in{640, 480, 457.0, 457.0, 319.5, 239.5, {}};
  const CameraIntrinsics half = in.Scaled(320, 240);
  EXPECT_DOUBLE_EQ(half.fx, 228.5);
  EXPECT_DOUBLE_EQ(half.cx, 159.5);
  EXPECT_DOUBLE_EQ(half.cy, 119.5);
}

// The share of the input's pixels that a distortion-free camera `out` of the same size shows.
double ShareOfInputShown(const CameraIntrinsics& in, const CameraIntrinsics& out) {
  std::vector<cv::Point2f> pixels;
  for (int y = 0; y < in.height; y += 4) {
    for (int x = 0; x < in.width; x += 4) pixels.emplace_back(x, y);
  }
  const cv::Matx33d k(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1);
  const cv::Matx33d k_out(out.fx, 0, out.cx, 0, out.fy, out.cy, 0, 0, 1);
  std::vector<cv::Point2f> undistorted;
  cv::undistortPoints(pixels, undistorted, k, cv::Mat(in.distortion, true), cv::noArray(), k_out);
  int shown = 0;
  for (const cv::Point2f& p : undistorted) {
    shown += p.x >= -0.5 && p.y >= -0.5 && p.x < in.width - 0.5 && p.y < in.height - 0.5;
  }
  return static_cast<double>(shown) / pixels.size();
}

TEST(CameraCalibration, RectifiedCameraShowsMostOfTheInputAndNoEmptyPixel) {
  const CameraIntrinsics plain{640, 480, 457.0, 457.0, 319.5, 239.5, {}};
  const CameraIntrinsics same = plain.Rectified();
  EXPECT_EQ(same.fx, plain.fx);
  EXPECT_EQ(same.cy, plain.cy);

  CameraIntrinsics wide = plain;  // barrel distortion of a wide-angle lens
  wide.distortion = {-0.28, 0.08, 0.0005, -0.0003, 0.0};
  const CameraIntrinsics r = wide.Rectified();
  EXPECT_FALSE(r.HasDistortion());
  EXPECT_EQ(r.width, 640);
  EXPECT_EQ(r.height, 480);
  // The input's own K shows under four fifths of it; the rectified camera more than nine tenths.
  CameraIntrinsics own_k = wide;
  own_k.distortion = {0, 0, 0, 0, 0};
  EXPECT_LT(ShareOfInputShown(wide, own_k), 0.80);
  EXPECT_GT(ShareOfInputShown(wide, r), 0.90);
  // Every border pixel of the rectified image lies inside the input: no pixel without data.
  const cv::Matx33d k(wide.fx, 0, wide.cx, 0, wide.fy, wide.cy, 0, 0, 1);
  std::vector<cv::Point3d> rays;
  for (int x = 0; x < 640; ++x) {
    for (int y : {0, 479}) rays.emplace_back((x - r.cx) / r.fx, (y - r.cy) / r.fy, 1.0);
  }
  for (int y = 0; y < 480; ++y) {
    for (int x : {0, 639}) rays.emplace_back((x - r.cx) / r.fx, (y - r.cy) / r.fy, 1.0);
  }
  std::vector<cv::Point2d> in_input;
  cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, cv::Mat(wide.distortion, true),
                    in_input);
  for (const cv::Point2d& q : in_input) {
    ASSERT_TRUE(q.x >= 0 && q.y >= 0 && q.x <= 639 && q.y <= 479) << q.x << ", " << q.y;
  }
}

struct BadCase {
  const char* file;
  const char* expected_key;     // the error must start with this key
  const char* expected_reason;  // and mention this
};

class MalformedCalibration : public ::testing::TestWithParam<BadCase> {};

TEST_P(MalformedCalibration, IsRejectedNamingTheKey) {
  const BadCase& bad = GetParam();
  CameraCalibration c;
  std::string error;
  const std::string path = kCalibDir + "/bad/" + bad.file;
  ASSERT_TRUE(std::filesystem::exists(path)) << path;
  EXPECT_FALSE(LoadCalibrationFile(path, &c, &error));
  const std::string prefix = path + ": " + bad.expected_key;
  EXPECT_EQ(error.rfind(prefix, 0), 0u) << "error: " << error << "\nexpected prefix: " << prefix;
  EXPECT_NE(error.find(bad.expected_reason), std::string::npos) << error;
}

INSTANTIATE_TEST_SUITE_P(
    AllFiles, MalformedCalibration,
    ::testing::Values(BadCase{"missing_camera.yaml", "camera:", "missing key"},
                      BadCase{"missing_mount.yaml", "mount:", "missing key"},
                      BadCase{"missing_fx.yaml", "camera.fx:", "missing key"},
                      BadCase{"unknown_camera_key.yaml", "camera.fz:", "unknown key"},
                      BadCase{"unknown_top_key.yaml", "robot:", "unknown key"},
                      BadCase{"list_key.yaml", "camera:", "keys must be names"},
                      BadCase{"unknown_mount_key.yaml", "mount.z:", "unknown key"},
                      BadCase{"fx_zero.yaml", "camera.fx:", "must be > 0"},
                      BadCase{"fy_negative.yaml", "camera.fy:", "must be > 0"},
                      BadCase{"cx_outside.yaml", "camera.cx:", "outside the image"},
                      BadCase{"cy_outside.yaml", "camera.cy:", "outside the image"},
                      BadCase{"height_zero.yaml", "mount.height:", "must be > 0"},
                      BadCase{"height_negative.yaml", "mount.height:", "must be > 0"},
                      BadCase{"pitch_90.yaml", "mount.pitch_deg:", "(-90, 90)"},
                      BadCase{"roll_95.yaml", "mount.roll_deg:", "(-90, 90)"},
                      BadCase{"nan_fy.yaml", "camera.fy:", "finite"},
                      BadCase{"yaw_inf.yaml", "mount.yaw_deg:", "finite"},
                      BadCase{"string_fx.yaml", "camera.fx:", "must be a number"},
                      BadCase{"width_float.yaml", "camera.width:", "must be an integer"},
                      BadCase{"width_zero.yaml", "camera.width:", "must be > 0"},
                      BadCase{"distortion_short.yaml", "camera.distortion:", "4 or 5 coefficients"},
                      BadCase{"distortion_scalar.yaml", "camera.distortion:", "must be a list"},
                      BadCase{"distortion_string.yaml", "camera.distortion:", "element 1"},
                      BadCase{"mount_list.yaml", "mount:", "must be a map"},
                      BadCase{"syntax_error.yaml", "YAML syntax error", "line"},
                      BadCase{"duplicate_key.yaml", "mount.pitch_deg:", "written twice (line 14)"},
                      BadCase{"ros_matrix_shape.yaml", "camera.camera_matrix.rows:", "3x3"}),
    [](const ::testing::TestParamInfo<BadCase>& param_info) {
      std::string name = param_info.param.file;
      return name.substr(0, name.find('.'));
    });

TEST(CameraCalibration, MissingFileIsNamed) {
  CameraCalibration c;
  std::string error;
  EXPECT_FALSE(LoadCalibrationFile("/nonexistent/calib.yaml", &c, &error));
  EXPECT_EQ(error, "/nonexistent/calib.yaml: cannot open file");
  // The error string of that failure, reused, does not make a good file fail.
  EXPECT_TRUE(LoadCalibrationFile(kCalibDir + "/default.yaml", &c, &error)) << error;
  CameraIntrinsics intrinsics;
  error = "left over";
  EXPECT_TRUE(LoadIntrinsicsFile(kCalibDir + "/default.yaml", &intrinsics, &error)) << error;
}

}  // namespace
}  // namespace monoplane
