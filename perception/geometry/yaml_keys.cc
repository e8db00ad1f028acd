#include "perception/geometry/yaml_keys.h"

#include <yaml-cpp/yaml.h>

#include <set>

namespace monoplane {
namespace {

std::string Find(const YAML::Node& node, const std::string& prefix) {
  if (node.IsMap()) {
    std::set<std::string> seen;
    for (const auto& kv : node) {
      const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : "?";
      const std::string path = prefix.empty() ? key : prefix + "." + key;
      if (kv.first.IsScalar() && !seen.insert(key).second)
        return path + ": written twice (line " + std::to_string(kv.first.Mark().line + 1) + ")";
      const std::string inner = Find(kv.second, path);
      if (!inner.empty()) return inner;
    }
  } else if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) {
      const std::string inner = Find(node[i], prefix + "[" + std::to_string(i) + "]");
      if (!inner.empty()) return inner;
    }
  }
  return {};
}

}  // namespace

std::string DuplicateYamlKey(const std::string& yaml_text) {
  try {
    return Find(YAML::Load(yaml_text), "");
  } catch (const YAML::Exception&) {
    return {};
  }
}

}  // namespace monoplane
