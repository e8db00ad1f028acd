#pragma once

#include <cstdint>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "app/input_source.h"
#include "interfaces/map_publisher.h"
#include "mapping/mapper.h"
#include "perception/geometry/pose2.h"
#include "perception/obstacle_detector.h"
#include "storage/map_database.h"

namespace monoplane::app {

// What `monoplane run` writes besides the map.
struct OutputOptions {
  // Write panels/NNNNNN.jpg for every N-th frame with --frames-out: the first frame with heights
  // at or after each multiple of N.
  int panels_every = 1;
  void Describe(OptionVisitor& v);  // keys, ranges and meanings (config.cc)
  bool IsValid(std::string* error) const;
};

// How `monoplane run` publishes over DDS with --publish.
struct PublishOptions {
  interfaces::MapPublisher::Options publisher;
  double map_period_s = 1.0;        // the global map goes out at most this often (stamps), s
  void Describe(OptionVisitor& v);  // the publisher's keys and map_period_s (config.cc)
  bool IsValid(std::string* error) const;
};

// Where a run that extends a saved map starts: the map pose of its first frame, the guess that
// localisation in the saved map starts from (Mapper::Options::localization_match sets the window).
struct StartOptions {
  double x_m = 0.0, y_m = 0.0, yaw_rad = 0.0;
  Pose2 pose() const { return Pose2{x_m, y_m, yaw_rad}; }
  void Describe(OptionVisitor& v);  // keys and meanings (config.cc)
};

// Every option of every module, settable from one YAML file (--config).
struct AppConfig {
  // monoplane run's defaults where they differ from the modules' own: every accepted loop closure
  // re-optimises the whole graph and may rebuild the maps, and driving back and forth over mapped
  // floor closes loops at nearly every keyframe; 10 keyframes between closures bound that cost on
  // long runs and still hold the trajectory.
  AppConfig() { mapping.loop_min_interval_keyframes = 10; }

  DetectorOptions detector;
  InputOptions input;
  OutputOptions output;
  Mapper::Options mapping;
  StartOptions start;
  MapDatabase::Options storage;
  PublishOptions dds;
  // The keys ("section.key") a config file set: ScaleDefaultsToCamera keeps their values.
  std::set<std::string> given;
};

// The camera the defaults are stated for: the simulator's robot camera, 0.40 m above the floor
// with a focal length of 457 px (640x480, 70 degrees across).
inline constexpr double kReferenceCameraHeightM = 0.40;
inline constexpr double kReferenceFocalPx = 457.0;

// Fits the defaults to the camera, so that one set of defaults serves a robot camera a few
// decimetres high and a car camera at 1.65 m. Lengths over the floor (the motion fit's strip, the
// pair baselines, the alignment's bound) scale with the camera's height over 0.40 m: a camera
// twice as high sees the same image of a scene twice as large. The detection range and the local
// map's extent and cells grow with a higher camera but do not shrink for a lower one: a room is as
// large for a low robot, and the parallax of a given height a few metres away hardly depends on
// the camera's height. The motion fit's pixel thresholds, which cover the camera's pitching
// between frames, scale with fx over 457 px, and the dense search's pyramid gets one more level
// per doubling of fx (rounded; never fewer). Keys in config->given keep their values; a camera at
// the reference height and focal length changes nothing.
void ScaleDefaultsToCamera(const CameraCalibration& calibration, AppConfig* config);

// Binds "section.key" names to option fields, for parsing YAML and for dumping the defaults.
// Keys not in the table are rejected with their name.
class OptionTable {
 public:
  explicit OptionTable(AppConfig* config);

  // Applies a YAML document (sections of keys). On failure names the key and the reason.
  bool Apply(const std::string& yaml_text, std::string* error);
  // The effective options as YAML with a comment per key.
  std::string Dump() const;

 private:
  struct Entry {
    std::string section, key, comment;
    std::function<bool(const std::string& value, std::string* error)> set;
    std::function<std::string()> get;
    double* number = nullptr;  // for ScaleDefaultsToCamera
    // kCameraHeightUp: with the camera's height, but never below the reference's value (what the
    // robot must see and map does not shrink with a lower camera).
    enum class Scale { kNone, kCameraHeight, kCameraHeightUp, kFocalLength } scale = Scale::kNone;
  };
  friend void ScaleDefaultsToCamera(const CameraCalibration& calibration, AppConfig* config);
  // The entry of "section.key"; throws std::logic_error when there is none (a renamed key).
  Entry& Named(const std::string& name);
  void ScaleWith(Entry::Scale scale, const std::vector<std::string>& names);
  void AddDouble(const std::string& section, const std::string& key, double* target,
                 const std::string& comment);
  void AddInt(const std::string& section, const std::string& key, int* target,
              const std::string& comment);
  void AddUnsigned(const std::string& section, const std::string& key, unsigned* target,
                   const std::string& comment);
  void AddFloat(const std::string& section, const std::string& key, float* target,
                const std::string& comment);
  void AddBool(const std::string& section, const std::string& key, bool* target,
               const std::string& comment);
  void AddString(const std::string& section, const std::string& key, std::string* target,
                 const std::string& comment);
  void AddInt64(const std::string& section, const std::string& key, std::int64_t* target,
                const std::string& comment);
  void AddChoice(const std::string& section, const std::string& key,
                 const std::function<int()>& get, const std::function<void(int)>& set,
                 const std::vector<std::string>& names, const std::string& comment);
  // Enters the fields `describe` lists (an options struct's Describe) under `section`.
  class Registrar;
  void AddSection(const std::string& section, const std::function<void(OptionVisitor&)>& describe);

  std::vector<Entry> entries_;
  AppConfig* config_;
};

// Applies a config document to *config (starting from its current values) and validates every
// module's options. Errors name the key and the reason.
bool ParseConfigYaml(const std::string& yaml_text, AppConfig* config, std::string* error);
// Reads a config file the same way. Errors start with the file's path.
bool LoadConfigFile(const std::string& path, AppConfig* config, std::string* error);
bool ValidateConfig(const AppConfig& config, std::string* error);

}  // namespace monoplane::app
