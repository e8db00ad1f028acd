#pragma once

#include <string>
#include <utility>
#include <vector>

#include "perception/geometry/timestamp.h"

namespace monoplane::app {

// A frame list: "<seconds> <image path>" per line, paths relative to `base`; empty lines and lines
// starting with '#' are skipped (TUM's rgb.txt has the same layout). Stamps must lie in
// [0, 9e9] s and increase strictly. On failure *error is "<file_label>:<line>: <reason>" and
// *frames holds the lines before it.
bool ParseTimesText(const std::string& text, const std::string& file_label, const std::string& base,
                    std::vector<std::pair<TimestampNs, std::string>>* frames, std::string* error);

// Reads and parses a times file (ParseTimesText, labelled with its path).
bool ReadTimesFile(const std::string& path, const std::string& base,
                   std::vector<std::pair<TimestampNs, std::string>>* frames, std::string* error);

}  // namespace monoplane::app
