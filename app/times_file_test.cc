#include "app/times_file.h"

#include <gtest/gtest.h>

namespace monoplane::app {
namespace {

using Frames = std::vector<std::pair<TimestampNs, std::string>>;

TEST(TimesFile, FramesInOrderWithPathsUnderTheFolder) {
  Frames frames;
  std::string error;
  ASSERT_TRUE(ParseTimesText("# stamp path\n\n0.0 images/a.png\n0.066\timages/b.png\n",
                             "seq/times.txt", "seq", &frames, &error))
      << error;
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0], (std::pair<TimestampNs, std::string>{0, "seq/images/a.png"}));
  EXPECT_EQ(frames[1].first, 66'000'000);
  EXPECT_EQ(frames[1].second, "seq/images/b.png");
}

TEST(TimesFile, BadLinesNameTheFileAndLineAndKeepTheFramesBefore) {
  const struct {
    const char* text;
    const char* error;
  } cases[] = {
      {"0.0 a.png\n6.0/b.png\n", "t.txt:2: expected '<seconds> <image path>'"},
      {"0.0 a.png\n0.5\n", "t.txt:2: expected '<seconds> <image path>'"},
      {"0.0 a.png\n1e300 b.png\n", "t.txt:2: time 1e300 s: must be in [0, 9e9] seconds"},
      {"0.0 a.png\n-1 b.png\n", "t.txt:2: time -1 s: must be in [0, 9e9] seconds"},
      {"0.0 a.png\n0.0 b.png\n",
       "t.txt:2: time 0.000000 s does not come after the previous frame's (times must increase)"},
  };
  for (const auto& c : cases) {
    Frames frames;
    std::string error;
    EXPECT_FALSE(ParseTimesText(c.text, "t.txt", ".", &frames, &error)) << c.text;
    EXPECT_EQ(error, c.error) << c.text;
    EXPECT_EQ(frames.size(), 1u) << c.text;
  }
}

TEST(TimesFile, AMissingFileIsNamed) {
  Frames frames;
  std::string error;
  EXPECT_FALSE(ReadTimesFile("/nonexistent/times.txt", "/nonexistent", &frames, &error));
  EXPECT_EQ(error, "/nonexistent/times.txt: cannot open");
}

}  // namespace
}  // namespace monoplane::app
