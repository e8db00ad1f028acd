// make_video IMAGE_DIR COUNT OUT.avi [KEEP_FRACTION]: the first COUNT images of IMAGE_DIR (sorted
// by name) as a Motion-JPEG AVI at 15 frames/s, for the CLI tests of video input
// (app/CMakeLists.txt). With KEEP_FRACTION in (0, 1) only that leading fraction of the file's
// bytes is kept: a truncated video whose header still announces COUNT frames.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  if (argc != 4 && argc != 5) {
    std::cerr << "usage: make_video IMAGE_DIR COUNT OUT.avi [KEEP_FRACTION]\n";
    return 2;
  }
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(argv[1])) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  const std::size_t count = std::min<std::size_t>(files.size(), std::stoul(argv[2]));
  if (count == 0) {
    std::cerr << argv[1] << ": no images\n";
    return 2;
  }
  const cv::Mat first = cv::imread(files[0].string(), cv::IMREAD_COLOR);
  cv::VideoWriter writer(argv[3], cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 15.0,
                         first.size());
  if (first.empty() || !writer.isOpened()) {
    std::cerr << argv[3] << ": cannot write an MJPG video\n";
    return 1;
  }
  for (std::size_t i = 0; i < count; ++i)
    writer.write(cv::imread(files[i].string(), cv::IMREAD_COLOR));
  writer.release();
  if (argc == 5) {
    const double keep = std::stod(argv[4]);
    const auto size = fs::file_size(argv[3]);
    fs::resize_file(argv[3], static_cast<std::uintmax_t>(keep * static_cast<double>(size)));
  }
  return 0;
}
