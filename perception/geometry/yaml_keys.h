#pragma once

#include <string>

namespace monoplane {

// The first key that a YAML map (at any depth) holds twice, as "path.to.key: written twice (line
// N)", or an empty string when there is none or the text does not parse (the parser reports
// that). YAML parsers keep one of the two values silently; a configuration or calibration file
// with a key written twice is refused instead of guessing which one was meant.
std::string DuplicateYamlKey(const std::string& yaml_text);

}  // namespace monoplane
