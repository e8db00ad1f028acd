#include "tools/sim/scene.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace monoplane::sim {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

const char* const kMaterialNames[kNumMaterials] = {"carpet",    "tiles",     "wood", "concrete",
                                                   "plain",     "paper",     "mat",  "tape",
                                                   "cardboard", "chessboard"};

// A failed parse: the message holds the key path.
struct ParseError {
  std::string message;
};

[[noreturn]] void Fail(const std::string& key, const std::string& what) {
  throw ParseError{key + ": " + what};
}

std::string Child(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}
std::string Index(const std::string& path, std::size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

void CheckKeys(const YAML::Node& node, const std::string& path,
               const std::set<std::string>& allowed) {
  if (!node.IsMap()) Fail(path.empty() ? "(top level)" : path, "expected a mapping");
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (!allowed.count(key)) Fail(Child(path, key), "unknown key");
  }
}

double ToDouble(const YAML::Node& node, const std::string& path) {
  if (!node.IsScalar()) Fail(path, "expected a number");
  double value = 0.0;
  try {
    value = node.as<double>();
  } catch (const YAML::Exception&) {
    Fail(path, "expected a number (got '" + node.Scalar() + "')");
  }
  if (!std::isfinite(value)) Fail(path, "must be finite");
  return value;
}

double GetDouble(const YAML::Node& map, const std::string& path, const std::string& key,
                 double fallback, bool required = false) {
  const YAML::Node node = map[key];
  if (!node) {
    if (required) Fail(Child(path, key), "missing");
    return fallback;
  }
  return ToDouble(node, Child(path, key));
}

double GetPositive(const YAML::Node& map, const std::string& path, const std::string& key,
                   double fallback, bool required = false) {
  const double v = GetDouble(map, path, key, fallback, required);
  if (!(v > 0)) Fail(Child(path, key), "must be > 0 (got " + std::to_string(v) + ")");
  return v;
}

double GetNonNegative(const YAML::Node& map, const std::string& path, const std::string& key,
                      double fallback) {
  const double v = GetDouble(map, path, key, fallback);
  if (v < 0) Fail(Child(path, key), "must be >= 0 (got " + std::to_string(v) + ")");
  return v;
}

int GetInt(const YAML::Node& map, const std::string& path, const std::string& key, int fallback,
           int min_value) {
  const double v = GetDouble(map, path, key, fallback);
  if (v != std::floor(v) || v < min_value || v > 1e9) {
    Fail(Child(path, key), "expected an integer >= " + std::to_string(min_value));
  }
  return static_cast<int>(v);
}

std::vector<double> Numbers(const YAML::Node& node, const std::string& path, std::size_t n) {
  if (!node.IsSequence() || node.size() != n) {
    Fail(path, "expected " + std::to_string(n) + " numbers");
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < n; ++i) out.push_back(ToDouble(node[i], Index(path, i)));
  return out;
}

Eigen::Vector2d GetVec2(const YAML::Node& map, const std::string& path, const std::string& key) {
  const YAML::Node node = map[key];
  if (!node) Fail(Child(path, key), "missing");
  const auto v = Numbers(node, Child(path, key), 2);
  return {v[0], v[1]};
}

Surface GetSurface(const YAML::Node& map, const std::string& path, Material fallback) {
  Surface s;
  s.material = fallback;
  if (const YAML::Node m = map["material"]) {
    const auto material = m.IsScalar() ? ParseMaterial(m.Scalar()) : std::nullopt;
    if (!material)
      Fail(Child(path, "material"),
           "unknown material '" + (m.IsScalar() ? m.Scalar() : std::string("?")) + "'");
    s.material = *material;
  }
  s.brightness = GetNonNegative(map, path, "brightness", 1.0);
  s.scale = GetPositive(map, path, "scale", 1.0);
  return s;
}

Rect GetRect(const YAML::Node& map, const std::string& path) {
  Rect r{GetVec2(map, path, "min"), GetVec2(map, path, "max")};
  if (!(r.max.x() > r.min.x() && r.max.y() > r.min.y()))
    Fail(Child(path, "max"), "must exceed min");
  return r;
}

YAML::Node CheckSequence(const YAML::Node& node, const std::string& path) {
  if (!node.IsSequence()) Fail(path, "expected a list");
  return node;
}

Shape ParseShape(const YAML::Node& node, const std::string& path, bool with_center) {
  Shape s;
  const std::string type = node["type"] && node["type"].IsScalar() ? node["type"].Scalar() : "";
  if (with_center) s.center = GetVec2(node, path, "center");
  s.z_m = GetDouble(node, path, "z", 0.0);
  s.surface = GetSurface(node, path, Material::kCardboard);
  if (type == "box") {
    CheckKeys(node, path,
              {"type", "center", "size", "yaw", "z", "material", "brightness", "scale", "speed",
               "waypoints", "loop", "start_time"});
    if (!node["size"]) Fail(Child(path, "size"), "missing");
    const auto v = Numbers(node["size"], Child(path, "size"), 3);
    for (std::size_t i = 0; i < 3; ++i) {
      if (!(v[i] > 0)) Fail(Index(Child(path, "size"), i), "must be > 0");
    }
    s.type = ShapeType::kBox;
    s.size = {v[0], v[1], v[2]};
    s.yaw_rad = GetDouble(node, path, "yaw", 0.0) * kDegToRad;
  } else if (type == "cylinder") {
    CheckKeys(node, path,
              {"type", "center", "radius", "height", "z", "material", "brightness", "scale",
               "speed", "waypoints", "loop", "start_time"});
    const double r = GetPositive(node, path, "radius", 0.0, true);
    s.type = ShapeType::kCylinder;
    s.size = {2 * r, 2 * r, GetPositive(node, path, "height", 0.0, true)};
  } else if (type == "sphere") {
    CheckKeys(node, path,
              {"type", "center", "radius", "z", "material", "brightness", "scale", "speed",
               "waypoints", "loop", "start_time"});
    const double r = GetPositive(node, path, "radius", 0.0, true);
    s.type = ShapeType::kSphere;
    s.size = {2 * r, 2 * r, 2 * r};
  } else {
    Fail(Child(path, "type"), "expected box, cylinder or sphere" +
                                  std::string(with_center ? " or table" : "") + " (got '" + type +
                                  "')");
  }
  return s;
}

void ParseTable(const YAML::Node& node, const std::string& path, std::vector<Shape>* out) {
  CheckKeys(node, path,
            {"type", "center", "size", "height", "yaw", "top", "leg", "z", "material", "brightness",
             "scale"});
  const Eigen::Vector2d center = GetVec2(node, path, "center");
  const Eigen::Vector2d size = GetVec2(node, path, "size");
  if (!(size.x() > 0 && size.y() > 0)) Fail(Child(path, "size"), "must be > 0");
  const double height = GetPositive(node, path, "height", 0.75);
  const double top = GetPositive(node, path, "top", 0.03);
  const double leg = GetPositive(node, path, "leg", 0.05);
  const double z = GetDouble(node, path, "z", 0.0);
  if (top >= height) Fail(Child(path, "top"), "must be < height");
  if (2 * leg >= std::min(size.x(), size.y())) Fail(Child(path, "leg"), "too thick for the top");
  const double yaw = GetDouble(node, path, "yaw", 0.0) * kDegToRad;
  const Surface surface = GetSurface(node, path, Material::kWood);
  const Pose2 world_from_table{center.x(), center.y(), yaw};
  Shape slab;
  slab.center = center;
  slab.z_m = z + height - top;
  slab.size = {size.x(), size.y(), top};
  slab.yaw_rad = yaw;
  slab.surface = surface;
  out->push_back(slab);
  for (int sx : {-1, 1}) {
    for (int sy : {-1, 1}) {
      Shape l = slab;
      l.center =
          world_from_table * Eigen::Vector2d(sx * (size.x() - leg) / 2, sy * (size.y() - leg) / 2);
      l.z_m = z;
      l.size = {leg, leg, height - top};
      out->push_back(l);
    }
  }
}

void ParseWall(const YAML::Node& node, const std::string& path, std::vector<Shape>* out) {
  CheckKeys(node, path, {"from", "to", "height", "thickness", "material", "brightness", "scale"});
  const Eigen::Vector2d a = GetVec2(node, path, "from"), b = GetVec2(node, path, "to");
  const double length = (b - a).norm();
  if (length <= 0) Fail(Child(path, "to"), "must differ from 'from'");
  Shape s;
  s.type = ShapeType::kBox;
  s.center = (a + b) / 2;
  s.yaw_rad = std::atan2(b.y() - a.y(), b.x() - a.x());
  s.size = {length, GetPositive(node, path, "thickness", 0.1),
            GetPositive(node, path, "height", 2.5)};
  s.surface = GetSurface(node, path, Material::kPlain);
  if (!node["brightness"]) s.surface.brightness = 0.9;
  out->push_back(s);
}

std::vector<VelocitySegment> WaypointSegments(const Pose2& start,
                                              const std::vector<Eigen::Vector2d>& waypoints,
                                              double speed, double turn_rate) {
  std::vector<VelocitySegment> segments;
  Eigen::Vector2d position = start.Translation();
  double yaw = start.yaw;
  for (const auto& w : waypoints) {
    const Eigen::Vector2d d = w - position;
    if (d.norm() < 1e-9) continue;
    const double turn = WrapAngle(std::atan2(d.y(), d.x()) - yaw);
    if (std::abs(turn) > 1e-9) {
      segments.push_back({0.0, std::copysign(turn_rate, turn), std::abs(turn) / turn_rate});
    }
    segments.push_back({speed, 0.0, d.norm() / speed});
    position = w;
    yaw += turn;
  }
  return segments;
}

void ParseTrajectory(const YAML::Node& node, Scene* scene) {
  const std::string path = "trajectory";
  CheckKeys(node, path, {"start", "segments", "waypoints", "speed", "turn_rate"});
  if (node["start"]) {
    const auto v = Numbers(node["start"], "trajectory.start", 3);
    scene->start = {v[0], v[1], v[2] * kDegToRad};
  }
  const bool has_segments = static_cast<bool>(node["segments"]);
  const bool has_waypoints = static_cast<bool>(node["waypoints"]);
  if (has_segments == has_waypoints) Fail(path, "give either segments or waypoints");
  if (has_segments) {
    if (node["speed"]) Fail("trajectory.speed", "only with waypoints");
    if (node["turn_rate"]) Fail("trajectory.turn_rate", "only with waypoints");
    const YAML::Node& list = CheckSequence(node["segments"], "trajectory.segments");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = Index("trajectory.segments", i);
      CheckKeys(list[i], p, {"v", "omega", "duration"});
      scene->segments.push_back({GetDouble(list[i], p, "v", 0.0),
                                 GetDouble(list[i], p, "omega", 0.0) * kDegToRad,
                                 GetPositive(list[i], p, "duration", 0.0, true)});
    }
  } else {
    const YAML::Node& list = CheckSequence(node["waypoints"], "trajectory.waypoints");
    std::vector<Eigen::Vector2d> waypoints;
    for (std::size_t i = 0; i < list.size(); ++i) {
      const auto v = Numbers(list[i], Index("trajectory.waypoints", i), 2);
      waypoints.emplace_back(v[0], v[1]);
    }
    scene->segments =
        WaypointSegments(scene->start, waypoints, GetPositive(node, path, "speed", 0.5),
                         GetPositive(node, path, "turn_rate", 60.0) * kDegToRad);
  }
}

void ParseScene(const YAML::Node& root, Scene* scene, const std::string& base_dir) {
  CheckKeys(root, "",
            {"calibration", "fps", "frames", "seed", "bounds", "light", "effects", "floor",
             "decals", "drops", "obstacles", "walls", "movers", "trajectory"});
  *scene = Scene();
  scene->calibration = DefaultSimCalibration();
  if (const YAML::Node c = root["calibration"]) {
    std::string error;
    bool ok = false;
    if (c.IsScalar()) {
      std::filesystem::path p(c.Scalar());
      if (p.is_relative()) p = std::filesystem::path(base_dir) / p;
      ok = LoadCalibrationFile(p.string(), &scene->calibration, &error);
    } else {
      YAML::Emitter emitter;
      emitter << c;
      ok = ParseCalibrationYaml(emitter.c_str(), &scene->calibration, &error);
    }
    if (!ok) Fail("calibration", error);
  }
  scene->fps = GetPositive(root, "", "fps", 15.0);
  scene->frames = GetInt(root, "", "frames", 0, 0);
  scene->seed = static_cast<unsigned>(GetInt(root, "", "seed", 1, 0));
  if (!root["bounds"]) Fail("bounds", "missing");
  const auto b = Numbers(root["bounds"], "bounds", 4);
  scene->bounds = {{b[0], b[1]}, {b[2], b[3]}};
  if (!(b[2] > b[0] && b[3] > b[1])) Fail("bounds", "need xmin < xmax and ymin < ymax");

  if (const YAML::Node l = root["light"]) {
    CheckKeys(l, "light", {"direction", "ambient", "diffuse", "sky"});
    if (l["direction"]) {
      const auto v = Numbers(l["direction"], "light.direction", 3);
      const Eigen::Vector3d d(v[0], v[1], v[2]);
      if (d.norm() < 1e-9) Fail("light.direction", "must not be zero");
      scene->light.direction = d.normalized();
    }
    scene->light.ambient = GetNonNegative(l, "light", "ambient", scene->light.ambient);
    scene->light.diffuse = GetNonNegative(l, "light", "diffuse", scene->light.diffuse);
    scene->light.sky = GetNonNegative(l, "light", "sky", scene->light.sky);
  }
  if (const YAML::Node e = root["effects"]) {
    CheckKeys(e, "effects", {"noise_sigma", "motion_blur_samples", "shutter_s", "exposure"});
    scene->effects.noise_sigma = GetNonNegative(e, "effects", "noise_sigma", 0.0);
    scene->effects.motion_blur_samples = GetInt(e, "effects", "motion_blur_samples", 1, 1);
    scene->effects.shutter_s = GetNonNegative(e, "effects", "shutter_s", 0.02);
    if (e["exposure"]) {
      const YAML::Node& list = CheckSequence(e["exposure"], "effects.exposure");
      for (std::size_t i = 0; i < list.size(); ++i) {
        const std::string p = Index("effects.exposure", i);
        CheckKeys(list[i], p, {"time", "gain"});
        ExposureKey k{GetDouble(list[i], p, "time", 0.0, true),
                      GetNonNegative(list[i], p, "gain", 1.0)};
        if (!scene->effects.exposure.empty() && k.time_s <= scene->effects.exposure.back().time_s) {
          Fail(p + ".time", "times must increase");
        }
        scene->effects.exposure.push_back(k);
      }
    }
  }
  scene->floor.material = Material::kCarpet;
  if (const YAML::Node f = root["floor"]) {
    CheckKeys(f, "floor", {"material", "brightness", "scale", "regions"});
    scene->floor = GetSurface(f, "floor", Material::kCarpet);
    if (f["regions"]) {
      const YAML::Node& list = CheckSequence(f["regions"], "floor.regions");
      for (std::size_t i = 0; i < list.size(); ++i) {
        const std::string p = Index("floor.regions", i);
        CheckKeys(list[i], p, {"min", "max", "material", "brightness", "scale", "seam"});
        scene->regions.push_back({GetRect(list[i], p), GetSurface(list[i], p, Material::kTiles),
                                  GetNonNegative(list[i], p, "seam", 0.0)});
      }
    }
  }
  if (root["decals"]) {
    const YAML::Node& list = CheckSequence(root["decals"], "decals");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = Index("decals", i);
      CheckKeys(
          list[i], p,
          {"material", "center", "size", "yaw", "brightness", "scale", "rows", "cols", "square"});
      Decal d;
      d.surface = GetSurface(list[i], p, Material::kPaper);
      d.center = GetVec2(list[i], p, "center");
      d.yaw_rad = GetDouble(list[i], p, "yaw", 0.0) * kDegToRad;
      if (d.surface.material == Material::kChessboard) {
        d.rows = GetInt(list[i], p, "rows", 0, 2);
        d.cols = GetInt(list[i], p, "cols", 0, 2);
        d.square_m = GetPositive(list[i], p, "square", 0.0, true);
        if (list[i]["size"])
          Fail(p + ".size", "derived from rows, cols and square for a chessboard");
        d.size = {d.cols * d.square_m, d.rows * d.square_m};
      } else {
        for (const char* k : {"rows", "cols", "square"}) {
          if (list[i][k]) Fail(Child(p, k), "only for material chessboard");
        }
        d.size = GetVec2(list[i], p, "size");
        if (!(d.size.x() > 0 && d.size.y() > 0)) Fail(p + ".size", "must be > 0");
      }
      scene->decals.push_back(d);
    }
  }
  if (root["drops"]) {
    const YAML::Node& list = CheckSequence(root["drops"], "drops");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = Index("drops", i);
      CheckKeys(list[i], p, {"min", "max", "depth", "material", "brightness", "scale"});
      scene->drops.push_back({GetRect(list[i], p), GetPositive(list[i], p, "depth", 0.0, true),
                              GetSurface(list[i], p, Material::kConcrete)});
    }
  }
  if (root["obstacles"]) {
    const YAML::Node& list = CheckSequence(root["obstacles"], "obstacles");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = Index("obstacles", i);
      if (!list[i].IsMap()) Fail(p, "expected a mapping");
      if (list[i]["type"] && list[i]["type"].IsScalar() && list[i]["type"].Scalar() == "table") {
        ParseTable(list[i], p, &scene->obstacles);
      } else {
        const YAML::Node& n = list[i];
        for (const char* k : {"speed", "waypoints", "loop", "start_time"}) {
          if (n[k]) Fail(Child(p, k), "unknown key (only for movers)");
        }
        scene->obstacles.push_back(ParseShape(n, p, true));
      }
    }
  }
  if (root["walls"]) {
    const YAML::Node& list = CheckSequence(root["walls"], "walls");
    for (std::size_t i = 0; i < list.size(); ++i)
      ParseWall(list[i], Index("walls", i), &scene->obstacles);
  }
  if (root["movers"]) {
    const YAML::Node& list = CheckSequence(root["movers"], "movers");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = Index("movers", i);
      if (!list[i].IsMap()) Fail(p, "expected a mapping");
      if (list[i]["center"]) Fail(p + ".center", "unknown key (movers follow waypoints)");
      Mover m;
      m.shape = ParseShape(list[i], p, false);
      if (m.shape.type == ShapeType::kSphere) Fail(p + ".type", "movers are box or cylinder");
      if (!list[i]["material"]) m.shape.surface.material = Material::kMat;
      m.speed_mps = GetPositive(list[i], p, "speed", 1.0);
      m.start_time_s = GetNonNegative(list[i], p, "start_time", 0.0);
      if (const YAML::Node loop = list[i]["loop"]) {
        try {
          m.loop = loop.as<bool>();
        } catch (const YAML::Exception&) {
          Fail(p + ".loop", "expected true or false");
        }
      }
      if (!list[i]["waypoints"]) Fail(p + ".waypoints", "missing");
      const YAML::Node& w = CheckSequence(list[i]["waypoints"], p + ".waypoints");
      for (std::size_t k = 0; k < w.size(); ++k) {
        const auto v = Numbers(w[k], Index(p + ".waypoints", k), 2);
        m.waypoints.emplace_back(v[0], v[1]);
      }
      if (m.waypoints.empty()) Fail(p + ".waypoints", "needs at least one waypoint");
      scene->movers.push_back(m);
    }
  }
  if (!root["trajectory"]) Fail("trajectory", "missing");
  ParseTrajectory(root["trajectory"], scene);
}

}  // namespace

const char* MaterialName(Material material) { return kMaterialNames[static_cast<int>(material)]; }

std::optional<Material> ParseMaterial(const std::string& name) {
  for (int i = 0; i < kNumMaterials; ++i) {
    if (name == kMaterialNames[i]) return static_cast<Material>(i);
  }
  return std::nullopt;
}

double Effects::GainAt(double time_s) const {
  if (exposure.empty()) return 1.0;
  if (time_s <= exposure.front().time_s) return exposure.front().gain;
  for (std::size_t i = 1; i < exposure.size(); ++i) {
    if (time_s <= exposure[i].time_s) {
      const double a =
          (time_s - exposure[i - 1].time_s) / (exposure[i].time_s - exposure[i - 1].time_s);
      return exposure[i - 1].gain + a * (exposure[i].gain - exposure[i - 1].gain);
    }
  }
  return exposure.back().gain;
}

double Scene::DurationS() const {
  double total = 0.0;
  for (const auto& s : segments) total += s.duration_s;
  return total;
}

int Scene::NumFrames() const {
  if (frames > 0) return frames;
  return static_cast<int>(std::floor(DurationS() * fps + 1e-9)) + 1;
}

CameraCalibration DefaultSimCalibration() {
  CameraCalibration c;
  c.intrinsics.width = 640;
  c.intrinsics.height = 480;
  c.intrinsics.fx = c.intrinsics.fy = 457.0;
  c.intrinsics.cx = 319.5;
  c.intrinsics.cy = 239.5;
  c.mount.x_m = 0.10;
  c.mount.y_m = 0.0;
  c.mount.height_m = 0.40;
  c.mount.pitch_deg = 22.0;
  return c;
}

bool ParseSceneYaml(const std::string& yaml_text, Scene* scene, std::string* error,
                    const std::string& base_dir) {
  try {
    const YAML::Node root = YAML::Load(yaml_text);
    ParseScene(root, scene, base_dir);
  } catch (const ParseError& e) {
    if (error) *error = e.message;
    return false;
  } catch (const YAML::Exception& e) {
    if (error) *error = std::string("YAML: ") + e.what();
    return false;
  }
  return true;
}

bool LoadSceneFile(const std::string& path, Scene* scene, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = path + ": cannot open";
    return false;
  }
  std::stringstream text;
  text << in.rdbuf();
  std::string inner;
  const std::string dir = std::filesystem::path(path).parent_path().string();
  if (!ParseSceneYaml(text.str(), scene, &inner, dir.empty() ? "." : dir)) {
    if (error) *error = path + ": " + inner;
    return false;
  }
  return true;
}

Pose2 RobotPoseAt(const Scene& scene, double time_s) {
  Pose2 pose = scene.start;
  double t = std::max(0.0, time_s);
  for (const auto& s : scene.segments) {
    const double dt = std::min(t, s.duration_s);
    // Exact integration of a constant-velocity arc in the robot frame.
    Pose2 step;
    step.yaw = s.omega_radps * dt;
    if (std::abs(s.omega_radps) < 1e-12) {
      step.x = s.v_mps * dt;
    } else {
      const double r = s.v_mps / s.omega_radps;
      step.x = r * std::sin(step.yaw);
      step.y = r * (1.0 - std::cos(step.yaw));
    }
    pose = pose * step;
    t -= dt;
    if (t <= 0) break;
  }
  return pose;
}

Pose2 MoverPoseAt(const Mover& mover, double time_s) {
  const auto& w = mover.waypoints;
  if (w.size() == 1) return {w[0].x(), w[0].y(), 0.0};
  // The path as a polyline: forward, then back (ping-pong) or closing to the start (loop).
  std::vector<Eigen::Vector2d> path = w;
  if (mover.loop) {
    path.push_back(w.front());
  } else {
    for (std::size_t i = w.size() - 1; i-- > 0;) path.push_back(w[i]);
  }
  double total = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) total += (path[i] - path[i - 1]).norm();
  if (total < 1e-12) return {w[0].x(), w[0].y(), 0.0};
  double s = std::fmod(std::max(0.0, time_s - mover.start_time_s) * mover.speed_mps, total);
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector2d d = path[i] - path[i - 1];
    const double len = d.norm();
    if (len < 1e-12) continue;
    if (s <= len || i + 1 == path.size()) {
      const Eigen::Vector2d p = path[i - 1] + d * std::min(1.0, s / len);
      return {p.x(), p.y(), std::atan2(d.y(), d.x())};
    }
    s -= len;
  }
  return {w[0].x(), w[0].y(), 0.0};
}

Shape MoverShapeAt(const Mover& mover, double time_s) {
  const Pose2 pose = MoverPoseAt(mover, time_s);
  Shape s = mover.shape;
  s.center = pose.Translation();
  if (s.type == ShapeType::kBox) s.yaw_rad = pose.yaw;
  return s;
}

}  // namespace monoplane::sim
