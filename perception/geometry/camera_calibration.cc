#include "perception/geometry/camera_calibration.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <set>
#include <sstream>
#include <vector>

#include "perception/geometry/yaml_keys.h"

namespace monoplane {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

std::string Describe(const YAML::Node& node) {
  if (node.IsScalar()) return "'" + node.Scalar() + "'";
  if (node.IsSequence()) return "a list";
  if (node.IsMap()) return "a map";
  return "nothing";
}

// Reads typed values from one YAML map, remembering the first error with the full key path.
class MapReader {
 public:
  MapReader(const YAML::Node& node, std::string path) : node_(node), path_(std::move(path)) {}

  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  bool Has(const char* key) const { return node_[key].IsDefined() && !node_[key].IsNull(); }

  void Double(const char* key, double* out, bool required = true) {
    if (!ok()) return;
    const YAML::Node v = node_[key];
    if (!v.IsDefined() || v.IsNull()) {
      if (required) Fail(key, "missing key");
      return;
    }
    if (!v.IsScalar()) return Fail(key, "must be a number (got " + Describe(v) + ")");
    try {
      *out = v.as<double>();
    } catch (const YAML::Exception&) {
      return Fail(key, "must be a number (got " + Describe(v) + ")");
    }
    if (!std::isfinite(*out)) Fail(key, "must be a finite number (got " + v.Scalar() + ")");
  }

  void Int(const char* key, int* out, bool required = true) {
    if (!ok()) return;
    const YAML::Node v = node_[key];
    if (!v.IsDefined() || v.IsNull()) {
      if (required) Fail(key, "missing key");
      return;
    }
    try {
      if (!v.IsScalar()) throw YAML::Exception(YAML::Mark(), "");
      *out = v.as<int>();
    } catch (const YAML::Exception&) {
      Fail(key, "must be an integer (got " + Describe(v) + ")");
    }
  }

  void Doubles(const char* key, std::vector<double>* out, bool required = true) {
    if (!ok()) return;
    const YAML::Node v = node_[key];
    if (!v.IsDefined() || v.IsNull()) {
      if (required) Fail(key, "missing key");
      return;
    }
    if (!v.IsSequence()) return Fail(key, "must be a list of numbers (got " + Describe(v) + ")");
    out->clear();
    for (std::size_t i = 0; i < v.size(); ++i) {
      try {
        out->push_back(v[i].as<double>());
      } catch (const YAML::Exception&) {
        return Fail(
            key, "element " + std::to_string(i) + " must be a number (got " + Describe(v[i]) + ")");
      }
      if (!std::isfinite(out->back())) {
        return Fail(key, "element " + std::to_string(i) + " must be finite");
      }
    }
  }

  YAML::Node Map(const char* key) {
    if (!ok()) return {};
    const YAML::Node v = node_[key];
    if (!v.IsDefined() || v.IsNull()) {
      Fail(key, "missing key");
      return {};
    }
    if (!v.IsMap()) Fail(key, "must be a map (got " + Describe(v) + ")");
    return v;
  }

  void RejectUnknown(const std::set<std::string>& known) {
    if (!ok()) return;
    for (const auto& kv : node_) {
      if (!kv.first.IsScalar()) {
        error_ = (path_.empty() ? "" : path_ + ": ") + "keys must be names (got a key that is " +
                 Describe(kv.first) + ")";
        return;
      }
      const std::string key = kv.first.Scalar();
      if (!known.count(key)) {
        std::string list;
        for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
        return Fail(key.c_str(), "unknown key (known: " + list + ")");
      }
    }
  }

  void Fail(const char* key, const std::string& reason) {
    if (ok()) error_ = Key(key) + ": " + reason;
  }
  std::string Key(const char* key) const { return path_.empty() ? key : path_ + "." + key; }

 private:
  YAML::Node node_;
  std::string path_;
  std::string error_;
};

// A ROS-style matrix node {rows, cols, data}; checks the shape.
bool ReadRosMatrix(const YAML::Node& node, const std::string& path, int rows, int cols,
                   std::vector<double>* data, std::string* error) {
  MapReader reader(node, path);
  int r = 0, c = 0;
  reader.Int("rows", &r);
  reader.Int("cols", &c);
  reader.Doubles("data", data);
  reader.RejectUnknown({"rows", "cols", "data", "dt"});  // "dt" appears in OpenCV's YAML flavour
  if (reader.ok() && (r != rows || (cols > 0 && c != cols))) {
    reader.Fail("rows", "expected a " + std::to_string(rows) + "x" +
                            (cols > 0 ? std::to_string(cols) : std::string("N")) + " matrix (got " +
                            std::to_string(r) + "x" + std::to_string(c) + ")");
  }
  if (reader.ok() && static_cast<int>(data->size()) != r * c) {
    reader.Fail("data", "has " + std::to_string(data->size()) +
                            " values, rows*cols = " + std::to_string(r * c));
  }
  if (!reader.ok()) *error = reader.error();
  return reader.ok();
}

bool ParseDistortion(const std::vector<double>& values, const std::string& key,
                     std::array<double, 5>* distortion, std::string* error) {
  // OpenCV writes 4, 5, 8, 12 or 14 coefficients; monoplane models the plumb-bob five, and accepts
  // longer vectors only when the extra (rational/thin-prism/tilt) terms are zero.
  if (values.size() < 4) {
    *error = key + ": needs 4 or 5 coefficients k1 k2 p1 p2 [k3] (got " +
             std::to_string(values.size()) + ")";
    return false;
  }
  for (std::size_t i = 5; i < values.size(); ++i) {
    if (values[i] != 0.0) {
      *error = key + ": coefficient " + std::to_string(i) +
               " is not zero; only the plumb-bob model k1 k2 p1 p2 k3 is supported";
      return false;
    }
  }
  distortion->fill(0.0);
  for (std::size_t i = 0; i < std::min<std::size_t>(5, values.size()); ++i) {
    (*distortion)[i] = values[i];
  }
  return true;
}

bool ParseCameraSection(const YAML::Node& camera, CameraIntrinsics* in, std::string* error) {
  MapReader reader(camera, "camera");
  if (camera["camera_matrix"].IsDefined() || camera["image_width"].IsDefined()) {
    // ROS camera_calibration layout.
    reader.Int("image_width", &in->width);
    reader.Int("image_height", &in->height);
    reader.RejectUnknown({"image_width", "image_height", "camera_name", "camera_matrix",
                          "distortion_model", "distortion_coefficients", "rectification_matrix",
                          "projection_matrix"});
    const YAML::Node km = reader.Map("camera_matrix");
    if (!reader.ok()) {
      *error = reader.error();
      return false;
    }
    std::vector<double> k;
    if (!ReadRosMatrix(km, "camera.camera_matrix", 3, 3, &k, error)) return false;
    in->fx = k[0];
    in->cx = k[2];
    in->fy = k[4];
    in->cy = k[5];
    if (k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0) {
      *error = "camera.camera_matrix: must be [fx 0 cx; 0 fy cy; 0 0 1]";
      return false;
    }
    if (camera["distortion_model"].IsDefined()) {
      const std::string model = camera["distortion_model"].as<std::string>("");
      if (model != "plumb_bob" && model != "rational_polynomial") {
        *error = "camera.distortion_model: unsupported model '" + model + "' (use plumb_bob)";
        return false;
      }
    }
    if (camera["distortion_coefficients"].IsDefined()) {
      std::vector<double> d;
      if (!ReadRosMatrix(camera["distortion_coefficients"], "camera.distortion_coefficients", 1, -1,
                         &d, error)) {
        return false;
      }
      if (!ParseDistortion(d, "camera.distortion_coefficients", &in->distortion, error)) {
        return false;
      }
    }
    return true;
  }
  reader.Int("width", &in->width);
  reader.Int("height", &in->height);
  reader.Double("fx", &in->fx);
  reader.Double("fy", &in->fy);
  reader.Double("cx", &in->cx);
  reader.Double("cy", &in->cy);
  std::vector<double> d;
  if (reader.Has("distortion")) reader.Doubles("distortion", &d);
  reader.RejectUnknown({"width", "height", "fx", "fy", "cx", "cy", "distortion"});
  if (!reader.ok()) {
    *error = reader.error();
    return false;
  }
  if (!d.empty() || reader.Has("distortion")) {
    if (d.size() != 4 && d.size() != 5) {
      *error = "camera.distortion: needs 4 or 5 coefficients k1 k2 p1 p2 [k3] (got " +
               std::to_string(d.size()) + ")";
      return false;
    }
    return ParseDistortion(d, "camera.distortion", &in->distortion, error);
  }
  return true;
}

bool ParseMountSection(const YAML::Node& mount, CameraMount* m, std::string* error) {
  MapReader reader(mount, "mount");
  reader.Double("x", &m->x_m);
  reader.Double("y", &m->y_m);
  reader.Double("height", &m->height_m);
  reader.Double("pitch_deg", &m->pitch_deg);
  reader.Double("roll_deg", &m->roll_deg);
  reader.Double("yaw_deg", &m->yaw_deg);
  reader.RejectUnknown({"x", "y", "height", "pitch_deg", "roll_deg", "yaw_deg"});
  if (!reader.ok()) *error = reader.error();
  return reader.ok();
}

bool ReadFile(const std::string& path, std::string* text, std::string* error) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    *error = path + ": cannot open file";
    return false;
  }
  std::ostringstream buffer;
  buffer << file.rdbuf();
  *text = buffer.str();
  return true;
}

std::string Num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

Eigen::Matrix3d CameraIntrinsics::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

bool CameraIntrinsics::HasDistortion() const {
  for (double d : distortion) {
    if (d != 0.0) return true;
  }
  return false;
}

CameraIntrinsics CameraIntrinsics::Scaled(int new_width, int new_height) const {
  CameraIntrinsics s = *this;
  const double sx = static_cast<double>(new_width) / width;
  const double sy = static_cast<double>(new_height) / height;
  s.width = new_width;
  s.height = new_height;
  s.fx *= sx;
  s.fy *= sy;
  // Pixel centres are integers: scale about the corner at (-0.5, -0.5).
  s.cx = (cx + 0.5) * sx - 0.5;
  s.cy = (cy + 0.5) * sy - 0.5;
  return s;
}

CameraIntrinsics CameraIntrinsics::Rectified() const {
  if (!HasDistortion()) return *this;
  const cv::Matx33d k(fx, 0, cx, 0, fy, cy, 0, 0, 1);
  const cv::Mat d(distortion, /*copyData=*/true);
  const cv::Size size(width, height);
  const cv::Matx33d k_new = cv::getOptimalNewCameraMatrix(k, d, size, 0.0, size);
  CameraIntrinsics own = *this;  // the input's camera matrix without the distortion
  own.distortion = {0, 0, 0, 0, 0};
  CameraIntrinsics r = own;
  // An estimate that is no camera of this image (not finite, not positive, its principal point
  // outside): start from the input's camera matrix instead.
  if (std::isfinite(k_new(0, 0)) && std::isfinite(k_new(1, 1)) && k_new(0, 0) > 0 &&
      k_new(1, 1) > 0 && k_new(0, 2) > 0 && k_new(1, 2) > 0 && k_new(0, 2) < width - 1 &&
      k_new(1, 2) < height - 1) {
    r.fx = k_new(0, 0);
    r.fy = k_new(1, 1);
    r.cx = k_new(0, 2);
    r.cy = k_new(1, 2);
  }
  // getOptimalNewCameraMatrix bounds the view by a coarse grid of points; check every border
  // pixel and narrow the view (larger focal lengths) until all of them lie inside the input. (On a
  // lens model that folds, its view already stays well inside the fold: k1 -1, k2 0.4 folds at
  // r^2 = 0.5, and its view reaches r^2 = 0.003.)
  std::vector<cv::Point3d> border;
  for (int x = 0; x < width; ++x) {
    border.emplace_back(x, 0, 1);
    border.emplace_back(x, height - 1, 1);
  }
  for (int y = 1; y + 1 < height; ++y) {
    border.emplace_back(0, y, 1);
    border.emplace_back(width - 1, y, 1);
  }
  for (int attempt = 0; attempt < 400; ++attempt) {  // up to 7.3 times the focal lengths
    std::vector<cv::Point3d> rays;
    rays.reserve(border.size());
    for (const cv::Point3d& p : border) {
      rays.emplace_back((p.x - r.cx) / r.fx, (p.y - r.cy) / r.fy, 1.0);
    }
    std::vector<cv::Point2d> in_input;
    cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, d, in_input);
    bool inside = true;
    for (const cv::Point2d& q : in_input) {
      inside = inside && q.x >= 0 && q.y >= 0 && q.x <= width - 1 && q.y <= height - 1;
    }
    if (inside) return r;
    r.fx *= 1.005;
    r.fy *= 1.005;
  }
  // No such view: the input's own camera matrix, whose view may reach past the input (those
  // pixels stay empty).
  return own;
}

CameraCalibration RectifiedCalibration(const CameraCalibration& calibration) {
  CameraCalibration r = calibration;
  r.intrinsics = calibration.intrinsics.Rectified();
  return r;
}

Eigen::Isometry3d CameraCalibration::BaseFromCamera() const {
  // Optical axes in the base frame for a level camera looking forward: z_opt = x_base,
  // x_opt = -y_base, y_opt = -z_base.
  Eigen::Matrix3d base_from_level_optical;
  base_from_level_optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(mount.yaw_deg * kDegToRad, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
      Eigen::AngleAxisd(mount.pitch_deg * kDegToRad, Eigen::Vector3d::UnitY()).toRotationMatrix() *
      base_from_level_optical *
      Eigen::AngleAxisd(mount.roll_deg * kDegToRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::Isometry3d base_from_camera = Eigen::Isometry3d::Identity();
  base_from_camera.linear() = rotation;
  base_from_camera.translation() = Eigen::Vector3d(mount.x_m, mount.y_m, mount.height_m);
  return base_from_camera;
}

bool CameraCalibration::IsValid(std::string* error) const {
  const CameraIntrinsics& in = intrinsics;
  auto fail = [&](const std::string& key, const std::string& reason) {
    *error = key + ": " + reason;
    return false;
  };
  if (in.width <= 0) return fail("camera.width", "must be > 0 pixels (got " + Num(in.width) + ")");
  if (in.height <= 0) {
    return fail("camera.height", "must be > 0 pixels (got " + Num(in.height) + ")");
  }
  const std::pair<const char*, double> finite[] = {{"camera.fx", in.fx},
                                                   {"camera.fy", in.fy},
                                                   {"camera.cx", in.cx},
                                                   {"camera.cy", in.cy},
                                                   {"mount.x", mount.x_m},
                                                   {"mount.y", mount.y_m},
                                                   {"mount.height", mount.height_m},
                                                   {"mount.pitch_deg", mount.pitch_deg},
                                                   {"mount.roll_deg", mount.roll_deg},
                                                   {"mount.yaw_deg", mount.yaw_deg}};
  for (const auto& [key, value] : finite) {
    if (!std::isfinite(value)) return fail(key, "must be a finite number");
  }
  for (std::size_t i = 0; i < in.distortion.size(); ++i) {
    if (!std::isfinite(in.distortion[i])) {
      return fail("camera.distortion", "element " + std::to_string(i) + " must be finite");
    }
  }
  if (in.fx <= 0) return fail("camera.fx", "must be > 0 pixels (got " + Num(in.fx) + ")");
  if (in.fy <= 0) return fail("camera.fy", "must be > 0 pixels (got " + Num(in.fy) + ")");
  if (in.cx < -0.5 || in.cx > in.width - 0.5) {
    return fail("camera.cx", "principal point outside the image [-0.5, " + Num(in.width - 0.5) +
                                 "] (got " + Num(in.cx) + ")");
  }
  if (in.cy < -0.5 || in.cy > in.height - 0.5) {
    return fail("camera.cy", "principal point outside the image [-0.5, " + Num(in.height - 0.5) +
                                 "] (got " + Num(in.cy) + ")");
  }
  if (mount.height_m <= 0) {
    return fail("mount.height", "must be > 0 m above the floor (got " + Num(mount.height_m) + ")");
  }
  if (std::abs(mount.pitch_deg) >= 90) {
    return fail("mount.pitch_deg",
                "must be in (-90, 90) degrees (got " + Num(mount.pitch_deg) + ")");
  }
  if (std::abs(mount.roll_deg) >= 90) {
    return fail("mount.roll_deg", "must be in (-90, 90) degrees (got " + Num(mount.roll_deg) + ")");
  }
  if (std::abs(mount.yaw_deg) > 180) {
    return fail("mount.yaw_deg", "must be in [-180, 180] degrees (got " + Num(mount.yaw_deg) + ")");
  }
  return true;
}

bool ParseCalibrationYaml(const std::string& yaml_text, CameraCalibration* calibration,
                          std::string* error) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    *error = "YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
    return false;
  }
  if (!root.IsMap()) {
    *error = "camera: missing key (the file is not a YAML map with camera: and mount:)";
    return false;
  }
  if (std::string duplicate = DuplicateYamlKey(yaml_text); !duplicate.empty()) {
    *error = std::move(duplicate);
    return false;
  }
  CameraCalibration parsed;
  try {
    MapReader reader(root, "");
    reader.RejectUnknown({"camera", "mount"});
    const YAML::Node camera = reader.Map("camera");
    const YAML::Node mount = reader.Map("mount");
    if (!reader.ok()) {
      *error = reader.error();
      return false;
    }
    if (!ParseCameraSection(camera, &parsed.intrinsics, error)) return false;
    if (!ParseMountSection(mount, &parsed.mount, error)) return false;
  } catch (const YAML::Exception& e) {
    *error = "YAML error: " + e.msg;
    return false;
  }
  if (!parsed.IsValid(error)) return false;
  *calibration = parsed;
  return true;
}

bool LoadCalibrationFile(const std::string& path, CameraCalibration* calibration,
                         std::string* error) {
  std::string text;
  if (!ReadFile(path, &text, error)) return false;
  if (!ParseCalibrationYaml(text, calibration, error)) {
    *error = path + ": " + *error;
    return false;
  }
  return true;
}

bool LoadIntrinsicsFile(const std::string& path, CameraIntrinsics* intrinsics, std::string* error) {
  std::string text;
  if (!ReadFile(path, &text, error)) return false;
  const bool opencv_flavour = text.rfind("%YAML:1.0", 0) == 0 || text.rfind("<?xml", 0) == 0 ||
                              text.find("!!opencv-matrix") != std::string::npos;
  CameraIntrinsics parsed;
  if (opencv_flavour) {
    // The cv::FileStorage dialect of OpenCV's calibration sample; yaml-cpp cannot read it.
    try {
      cv::FileStorage fs(path, cv::FileStorage::READ);
      cv::Mat k, d;
      fs["camera_matrix"] >> k;
      fs["distortion_coefficients"] >> d;
      fs["image_width"] >> parsed.width;
      fs["image_height"] >> parsed.height;
      if (k.empty()) {
        *error = path + ": camera_matrix: missing key";
        return false;
      }
      if (k.rows != 3 || k.cols != 3) {
        *error = path + ": camera_matrix: must be 3x3";
        return false;
      }
      k.convertTo(k, CV_64F);
      parsed.fx = k.at<double>(0, 0);
      parsed.fy = k.at<double>(1, 1);
      parsed.cx = k.at<double>(0, 2);
      parsed.cy = k.at<double>(1, 2);
      if (!d.empty()) {
        d.convertTo(d, CV_64F);
        std::vector<double> values(d.begin<double>(), d.end<double>());
        if (!ParseDistortion(values, "distortion_coefficients", &parsed.distortion, error)) {
          *error = path + ": " + *error;
          return false;
        }
      }
    } catch (const cv::Exception& e) {
      *error = path + ": cannot parse OpenCV calibration file: " + e.msg;
      return false;
    }
  } else {
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      *error =
          path + ": YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
      return false;
    }
    if (!root.IsMap()) {
      *error = path + ": not a calibration file (expected a YAML map)";
      return false;
    }
    if (std::string duplicate = DuplicateYamlKey(text); !duplicate.empty()) {
      *error = path + ": " + duplicate;
      return false;
    }
    // monoplane's own file: take its camera: section; ROS's file: the root is the camera section.
    const YAML::Node camera = root["camera"].IsMap() ? root["camera"] : root;
    try {
      if (!ParseCameraSection(camera, &parsed, error)) {
        *error = path + ": " + *error;
        return false;
      }
    } catch (const YAML::Exception& e) {
      *error = path + ": YAML error: " + e.msg;
      return false;
    }
  }
  CameraCalibration check;
  check.intrinsics = parsed;
  check.mount.height_m = 1.0;  // the mount is not part of this file
  if (!check.IsValid(error)) {
    *error = path + ": " + *error;
    return false;
  }
  *intrinsics = parsed;
  return true;
}

std::string CalibrationToYaml(const CameraCalibration& c) {
  std::ostringstream out;
  out.precision(17);
  const CameraIntrinsics& in = c.intrinsics;
  out << "camera:\n"
      << "  width: " << in.width << "\n"
      << "  height: " << in.height << "\n"
      << "  fx: " << in.fx << "\n"
      << "  fy: " << in.fy << "\n"
      << "  cx: " << in.cx << "\n"
      << "  cy: " << in.cy << "\n"
      << "  distortion: [" << in.distortion[0] << ", " << in.distortion[1] << ", "
      << in.distortion[2] << ", " << in.distortion[3] << ", " << in.distortion[4] << "]\n"
      << "mount:\n"
      << "  x: " << c.mount.x_m << "\n"
      << "  y: " << c.mount.y_m << "\n"
      << "  height: " << c.mount.height_m << "\n"
      << "  pitch_deg: " << c.mount.pitch_deg << "\n"
      << "  roll_deg: " << c.mount.roll_deg << "\n"
      << "  yaw_deg: " << c.mount.yaw_deg << "\n";
  return out.str();
}

}  // namespace monoplane
