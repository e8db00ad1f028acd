#include "app/times_file.h"

#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace monoplane::app {

bool ParseTimesText(const std::string& text, const std::string& file_label, const std::string& base,
                    std::vector<std::pair<TimestampNs, std::string>>* frames, std::string* error) {
  std::istringstream in(text);
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double seconds = 0;
    std::string path;
    const std::string where = file_label + ":" + std::to_string(line_number);
    // Whitespace must separate the fields ("6.0/a.png" is not a time and a path).
    const bool separated = (fields >> seconds) && std::isspace(fields.peek());
    if (!separated || !(fields >> path)) {
      *error = where + ": expected '<seconds> <image path>'";
      return false;
    }
    // Stamps become int64 nanoseconds (up to 9.2e9 s) and order the frames: each must be a time
    // and come after the one before.
    if (!(seconds >= 0.0 && seconds <= 9e9)) {
      *error = where + ": time " + line.substr(0, line.find_first_of(" \t")) +
               " s: must be in [0, 9e9] seconds";
      return false;
    }
    const TimestampNs stamp = SecondsToNs(seconds);
    if (!frames->empty() && stamp <= frames->back().first) {
      *error = where + ": time " + std::to_string(seconds) +
               " s does not come after the previous frame's (times must increase)";
      return false;
    }
    frames->emplace_back(stamp, (std::filesystem::path(base) / path).string());
  }
  return true;
}

bool ReadTimesFile(const std::string& path, const std::string& base,
                   std::vector<std::pair<TimestampNs, std::string>>* frames, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open";
    return false;
  }
  std::ostringstream text;
  text << in.rdbuf();
  return ParseTimesText(text.str(), path, base, frames, error);
}

}  // namespace monoplane::app
