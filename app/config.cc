#include "app/config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <type_traits>

#include "perception/geometry/yaml_keys.h"

namespace monoplane::app {

void InputOptions::Describe(OptionVisitor& v) {
  v.Real("fps", &fps, OptionRange::Above(0), "frame rate for inputs without timestamps, Hz");
}

void OutputOptions::Describe(OptionVisitor& v) {
  v.Integer("panels_every", &panels_every, OptionRange::AtLeast(1),
            "panels every N-th frame (the first with heights from there) with --frames-out");
}

bool OutputOptions::IsValid(std::string* error) const {
  return CheckOptions(*this, "output", error);
}

void PublishOptions::Describe(OptionVisitor& v) {
  publisher.Describe(v);
  v.Real("map_period_s", &map_period_s, OptionRange::AtLeast(0),
         "global map published at most this often, s");
}

bool PublishOptions::IsValid(std::string* error) const { return CheckOptions(*this, "dds", error); }

void StartOptions::Describe(OptionVisitor& v) {
  v.Real("x_m", &x_m, OptionRange::Any(), "extending a map: map x of the first frame, m");
  v.Real("y_m", &y_m, OptionRange::Any(), "extending a map: map y of the first frame, m");
  v.Real("yaw_rad", &yaw_rad, OptionRange::Any(),
         "extending a map: map yaw of the first frame, rad");
}

// Enters each field a description lists into the table as "<section>.<key>", its comment the
// meaning and the range.
class OptionTable::Registrar : public OptionVisitor {
 public:
  Registrar(OptionTable* table, std::string section)
      : table_(table), section_(std::move(section)) {}
  void Real(const std::string& key, double* value, const OptionRange& range,
            const std::string& meaning) override {
    table_->AddDouble(section_, key, value, Comment(meaning, range));
  }
  void Real(const std::string& key, float* value, const OptionRange& range,
            const std::string& meaning) override {
    table_->AddFloat(section_, key, value, Comment(meaning, range));
  }
  void Integer(const std::string& key, int* value, const OptionRange& range,
               const std::string& meaning) override {
    table_->AddInt(section_, key, value, Comment(meaning, range));
  }
  void Integer(const std::string& key, std::int64_t* value, const OptionRange& range,
               const std::string& meaning) override {
    table_->AddInt64(section_, key, value, Comment(meaning, range));
  }
  void Integer(const std::string& key, unsigned* value, const OptionRange& range,
               const std::string& meaning) override {
    table_->AddUnsigned(section_, key, value, Comment(meaning, range));
  }
  void Flag(const std::string& key, bool* value, const std::string& meaning) override {
    table_->AddBool(section_, key, value, meaning);
  }
  void Text(const std::string& key, std::string* value, const std::string& meaning) override {
    table_->AddString(section_, key, value, meaning);
  }
  void Choice(const std::string& key, const std::function<int()>& get,
              const std::function<void(int)>& set, const std::vector<std::string>& names,
              const std::string& meaning) override {
    table_->AddChoice(section_, key, get, set, names, meaning);
  }

 private:
  static std::string Comment(const std::string& meaning, const OptionRange& range) {
    const std::string text = range.Text();
    return text.empty() ? meaning : meaning + " (" + text + ")";
  }
  OptionTable* table_;
  std::string section_;
};

void OptionTable::AddSection(const std::string& section,
                             const std::function<void(OptionVisitor&)>& describe) {
  Registrar registrar(this, section);
  describe(registrar);
}

OptionTable::OptionTable(AppConfig* config) : config_(config) {
  DetectorOptions& d = config->detector;
  AddSection("ground_motion", [&](OptionVisitor& v) { d.ground_motion.Describe(v); });
  AddSection("direct_alignment", [&](OptionVisitor& v) { d.direct_alignment.Describe(v); });
  AddSection("zero_disparity", [&](OptionVisitor& v) { d.zero_disparity.Describe(v); });
  AddSection("classification", [&](OptionVisitor& v) { d.classification.Describe(v); });
  AddSection("local_map", [&](OptionVisitor& v) { d.local_map.Describe(v); });
  AddSection("pair_selection", [&](OptionVisitor& v) { d.pair_selection.Describe(v); });
  AddSection("height_filter", [&](OptionVisitor& v) { d.height_filter.Describe(v); });
  AddSection("motion_evidence", [&](OptionVisitor& v) { d.motion_evidence.Describe(v); });
  AddSection("moving_objects", [&](OptionVisitor& v) { d.moving_objects.Describe(v); });
  AddSection("floor_features", [&](OptionVisitor& v) { d.floor_features.Describe(v); });
  AddSection("mapping", [&](OptionVisitor& v) { config->mapping.Describe(v); });
  AddSection("start", [&](OptionVisitor& v) { config->start.Describe(v); });
  AddSection("storage", [&](OptionVisitor& v) { config->storage.Describe(v); });
  AddSection("dds", [&](OptionVisitor& v) { config->dds.Describe(v); });
  AddSection("input", [&](OptionVisitor& v) { config->input.Describe(v); });
  AddSection("output", [&](OptionVisitor& v) { config->output.Describe(v); });
  // ScaleDefaultsToCamera: the sizes of what the camera sees, and the motion fit's tolerance of
  // the camera pitching between frames.
  ScaleWith(Entry::Scale::kCameraHeight,
            {"ground_motion.strip_min_x_m", "ground_motion.strip_max_x_m",
             "ground_motion.strip_half_width_m", "pair_selection.min_baseline_m",
             "pair_selection.far_min_baseline_m", "pair_selection.turn_min_baseline_m",
             "pair_selection.turn_side_min_baseline_m", "pair_selection.close_min_baseline_m",
             "direct_alignment.max_correction_m", "ground_motion.lowest_surface_tolerance_m",
             "ground_motion.lowest_surface_max_m_per_px",
             "ground_motion.lowest_surface_min_offset_m", "mapping.window_floor_max_height_m"});
  ScaleWith(Entry::Scale::kCameraHeightUp,
            {"classification.max_range_m", "mapping.full_hit_range_m", "mapping.carve_max_range_m",
             "local_map.resolution_m", "local_map.min_x_m", "local_map.max_x_m",
             "local_map.min_y_m", "local_map.max_y_m"});
  ScaleWith(Entry::Scale::kFocalLength,
            {"ground_motion.inlier_threshold_px", "ground_motion.below_floor_px"});
  Named("zero_disparity.num_levels").comment +=
      "; default: one more per doubling of fx over 457 px";
  for (const char* turn :
       {"pair_selection.turn_min_baseline_m", "pair_selection.turn_side_min_baseline_m"})
    Named(turn).comment += ", up to what a turn on the spot moves the camera";
}

namespace {

// A setter that parses the whole string with `parse` (std::stod, std::stoi, ...) into *target.
template <typename T, typename Parse>
auto NumberSetter(T* target, Parse parse, const char* what) {
  return [target, parse, what](const std::string& v, std::string* error) {
    try {
      std::size_t used = 0;
      const auto value = parse(v, &used);
      if (used != v.size() || (std::is_unsigned_v<T> && v.find('-') != std::string::npos)) {
        throw std::invalid_argument(v);
      }
      *target = static_cast<T>(value);
      return true;
    } catch (const std::exception&) {
      *error = std::string("must be ") + what + " (got '" + v + "')";
      return false;
    }
  };
}

}  // namespace

void OptionTable::AddDouble(const std::string& section, const std::string& key, double* target,
                            const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stod(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "a number"),
                      [target] { return FormatOptionValue(*target); }, target});
}

OptionTable::Entry& OptionTable::Named(const std::string& name) {
  auto it = std::find_if(entries_.begin(), entries_.end(),
                         [&](const Entry& e) { return e.section + "." + e.key == name; });
  if (it == entries_.end()) throw std::logic_error("OptionTable: no option " + name);
  return *it;
}

void OptionTable::ScaleWith(Entry::Scale scale, const std::vector<std::string>& names) {
  for (const std::string& name : names) {
    Entry& e = Named(name);
    if (e.number == nullptr)
      throw std::logic_error("OptionTable::ScaleWith: not a number: " + name);
    e.scale = scale;
    e.comment += scale == Entry::Scale::kCameraHeight ? "; default scales with camera height"
                 : scale == Entry::Scale::kCameraHeightUp
                     ? "; default grows with camera height above 0.40 m"
                     : "; default scales with fx";
  }
}

void ScaleDefaultsToCamera(const CameraCalibration& calibration, AppConfig* config) {
  const double by_height = calibration.mount.height_m / kReferenceCameraHeightM;
  const double by_focal = calibration.intrinsics.fx / kReferenceFocalPx;
  OptionTable table(config);
  for (const OptionTable::Entry& e : table.entries_) {
    if (e.scale == OptionTable::Entry::Scale::kNone || config->given.count(e.section + "." + e.key))
      continue;
    switch (e.scale) {
      case OptionTable::Entry::Scale::kCameraHeight:
        *e.number *= by_height;
        break;
      case OptionTable::Entry::Scale::kCameraHeightUp:
        *e.number *= std::max(1.0, by_height);
        break;
      case OptionTable::Entry::Scale::kFocalLength:
        *e.number *= by_focal;
        break;
      case OptionTable::Entry::Scale::kNone:
        break;
    }
  }
  // A turn on the spot moves the camera only by its distance from the base origin (the axle) per
  // radian: a turning pair's baselines grow with the camera's height only as far as
  // turn_max_rotation_rad of turning gives (four fifths of it), never below the reference's, or a
  // taller camera finds no turning pair at all.
  PairSelectionOptions& ps = config->detector.pair_selection;
  const PairSelectionOptions reference;
  const double turn_travel_m =
      0.8 * std::hypot(calibration.mount.x_m, calibration.mount.y_m) * ps.turn_max_rotation_rad;
  for (const auto& [key, value, reference_value] :
       {std::tuple{"pair_selection.turn_min_baseline_m", &ps.turn_min_baseline_m,
                   reference.turn_min_baseline_m},
        std::tuple{"pair_selection.turn_side_min_baseline_m", &ps.turn_side_min_baseline_m,
                   reference.turn_side_min_baseline_m}}) {
    if (!config->given.count(key))
      *value = std::min(*value, std::max(turn_travel_m, reference_value));
  }
  // The dense search's pyramid: every parallax in pixels grows with the focal length, so a
  // camera with twice the reference's fx gets one more level, which keeps the coarsest level's
  // reach the same angle (never fewer levels than the reference's).
  if (!config->given.count("zero_disparity.num_levels") && by_focal > 1.0) {
    int& levels = config->detector.zero_disparity.num_levels;
    levels = std::min(ZeroDisparityOptions::kMaxLevels,
                      levels + static_cast<int>(std::lround(std::log2(by_focal))));
  }
}

void OptionTable::AddFloat(const std::string& section, const std::string& key, float* target,
                           const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stof(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "a number"),
                      [target] { return FormatOptionValue(*target); }});
}

void OptionTable::AddInt(const std::string& section, const std::string& key, int* target,
                         const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stoi(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "an integer"),
                      [target] { return std::to_string(*target); }});
}

void OptionTable::AddInt64(const std::string& section, const std::string& key, std::int64_t* target,
                           const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stoll(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "an integer"),
                      [target] { return std::to_string(*target); }});
}

void OptionTable::AddUnsigned(const std::string& section, const std::string& key, unsigned* target,
                              const std::string& comment) {
  auto parse = [](const std::string& v, std::size_t* used) { return std::stoul(v, used); };
  entries_.push_back({section, key, comment, NumberSetter(target, parse, "a non-negative integer"),
                      [target] { return std::to_string(*target); }});
}

void OptionTable::AddBool(const std::string& section, const std::string& key, bool* target,
                          const std::string& comment) {
  entries_.push_back({section, key, comment,
                      [target](const std::string& v, std::string* error) {
                        if (v == "true" || v == "yes" || v == "on") {
                          *target = true;
                        } else if (v == "false" || v == "no" || v == "off") {
                          *target = false;
                        } else {
                          *error = "must be true or false (got '" + v + "')";
                          return false;
                        }
                        return true;
                      },
                      [target] { return std::string(*target ? "true" : "false"); }});
}

void OptionTable::AddString(const std::string& section, const std::string& key, std::string* target,
                            const std::string& comment) {
  entries_.push_back({section, key, comment,
                      [target](const std::string& v, std::string*) {
                        *target = v;
                        return true;
                      },
                      [target] {
                        YAML::Emitter quoted;  // escapes quotes, backslashes, control characters
                        quoted << YAML::DoubleQuoted << *target;
                        return std::string(quoted.c_str());
                      }});
}

void OptionTable::AddChoice(const std::string& section, const std::string& key,
                            const std::function<int()>& get, const std::function<void(int)>& set,
                            const std::vector<std::string>& names, const std::string& comment) {
  entries_.push_back({section, key, comment,
                      [set, names](const std::string& v, std::string* error) {
                        for (std::size_t i = 0; i < names.size(); ++i) {
                          if (names[i] == v) {
                            set(static_cast<int>(i));
                            return true;
                          }
                        }
                        std::string list;
                        for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
                        *error = "must be one of " + list + " (got '" + v + "')";
                        return false;
                      },
                      [get, names] { return names[static_cast<std::size_t>(get())]; }});
}

bool OptionTable::Apply(const std::string& yaml_text, std::string* error) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    *error = "YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
    return false;
  }
  if (root.IsNull()) return true;  // an empty file changes nothing
  if (!root.IsMap()) {
    *error = "the config must be a YAML map of sections";
    return false;
  }
  if (std::string duplicate = DuplicateYamlKey(yaml_text); !duplicate.empty()) {
    *error = std::move(duplicate);
    return false;
  }
  for (const auto& section : root) {
    if (!section.first.IsScalar()) {
      *error = "section names must be names (got a list or a map as a key)";
      return false;
    }
    const std::string name = section.first.Scalar();
    bool known_section = false;
    for (const Entry& e : entries_) known_section |= e.section == name;
    if (!known_section) {
      *error = name + ": unknown section";
      return false;
    }
    if (!section.second.IsMap()) {
      *error = name + ": must be a map of keys";
      return false;
    }
    for (const auto& kv : section.second) {
      if (!kv.first.IsScalar()) {
        *error = name + ": keys must be names (got a list or a map as a key)";
        return false;
      }
      const std::string key = kv.first.Scalar();
      auto it = std::find_if(entries_.begin(), entries_.end(),
                             [&](const Entry& e) { return e.section == name && e.key == key; });
      if (it == entries_.end()) {
        *error = name + "." + key + ": unknown key";
        return false;
      }
      if (!kv.second.IsScalar()) {
        *error = name + "." + key + ": must be a single value";
        return false;
      }
      std::string reason;
      if (!it->set(kv.second.Scalar(), &reason)) {
        *error = name + "." + key + ": " + reason;
        return false;
      }
      config_->given.insert(name + "." + key);
    }
  }
  return true;
}

std::string OptionTable::Dump() const {
  std::ostringstream out;
  out << "# monoplane options (monoplane run --config FILE); every key is optional.\n";
  std::string section;
  for (const Entry& e : entries_) {
    if (e.section != section) {
      section = e.section;
      out << section << ":\n";
    }
    std::string line = "  " + e.key + ": " + e.get();
    line.resize(std::max<std::size_t>(line.size() + 1, 40), ' ');
    out << line << "# " << e.comment << "\n";
  }
  return out.str();
}

bool ValidateConfig(const AppConfig& config, std::string* error) {
  return CheckOptions(config.input, "input", error) && config.detector.IsValid(error) &&
         config.mapping.IsValid(error) && CheckOptions(config.start, "start", error) &&
         config.storage.IsValid(error) && config.output.IsValid(error) && config.dds.IsValid(error);
}

bool LoadConfigFile(const std::string& path, AppConfig* config, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open file";
    return false;
  }
  std::ostringstream text;
  text << in.rdbuf();
  std::string reason;
  if (!ParseConfigYaml(text.str(), config, &reason)) {
    *error = path + ": " + reason;
    return false;
  }
  return true;
}

bool ParseConfigYaml(const std::string& yaml_text, AppConfig* config, std::string* error) {
  OptionTable table(config);
  if (!table.Apply(yaml_text, error)) return false;
  return ValidateConfig(*config, error);
}

}  // namespace monoplane::app
