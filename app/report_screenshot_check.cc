// Checks a browser's screenshot of `monoplane report`'s page (CTest app/report_renders): the map
// picture was decoded and drawn, not a broken image or a blank page. The picture is the only
// thing on the page with the map picture's unknown grey (160, 160, 160: storage/map_export.cc); a
// broken image or a blank page shows none of it.
//   report_screenshot_check SCREENSHOT.png
// Prints "map visible: N unknown-grey px" and exits 0, or says what is missing and exits 1.
#include <cstdio>
#include <opencv2/imgcodecs.hpp>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: report_screenshot_check SCREENSHOT.png\n");
    return 2;
  }
  const cv::Mat shot = cv::imread(argv[1], cv::IMREAD_COLOR);
  if (shot.empty()) {
    std::fprintf(stderr, "%s: not an image\n", argv[1]);
    return 1;
  }
  long grey = 0;
  for (int y = 0; y < shot.rows; ++y) {
    const cv::Vec3b* row = shot.ptr<cv::Vec3b>(y);
    for (int x = 0; x < shot.cols; ++x) {
      const cv::Vec3b p = row[x];
      if (p[0] == 160 && p[1] == 160 && p[2] == 160) ++grey;
    }
  }
  std::printf("map visible: %ld unknown-grey px\n", grey);
  // At 800 px across, even a small map's unknown area covers tens of thousands of pixels.
  if (grey < 20000) {
    std::fprintf(stderr, "%s: the map picture is not on the page\n", argv[1]);
    return 1;
  }
  return 0;
}
