// Fuzz target: times.txt (and TUM's rgb.txt). Any text is either refused with the line named, or
// gives frames with strictly increasing stamps in [0, 9e9] s, one per line that is not a comment.
#include <cctype>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "app/times_file.h"
#include "fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace monoplane;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::pair<TimestampNs, std::string>> frames;
  std::string error;
  if (!app::ParseTimesText(text, "times.txt", "/seq", &frames, &error)) {
    FuzzCheck(error.rfind("times.txt:", 0) == 0, "a refused file names the file and line");
    return 0;
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    FuzzCheck(frames[i].first >= 0 && frames[i].first <= SecondsToNs(9e9),
              "stamps within [0, 9e9] s");
    FuzzCheck(i == 0 || frames[i].first > frames[i - 1].first, "stamps increase");
    // A relative path is read under the sequence folder (an absolute one as it is).
    bool written_as_absolute = false;  // the path appears in the text after whitespace
    for (std::size_t at = text.find(frames[i].second); at != std::string::npos && at > 0;
         at = text.find(frames[i].second, at + 1)) {
      written_as_absolute |= std::isspace(static_cast<unsigned char>(text[at - 1])) != 0;
    }
    FuzzCheck(frames[i].second.rfind("/seq/", 0) == 0 || written_as_absolute,
              "relative paths are under the sequence folder");
  }
  return 0;
}
