#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "perception/frame_types.h"
#include "perception/obstacle_detector.h"

namespace monoplane::app {

// Writes the per-frame outputs of ../shared/INTERFACES.md for frame `index` under `dir`:
// labels/NNNNNN.png, height/NNNNNN.png (in the input image's pixels: lens distortion put back),
// local/NNNNNN.yaml + .pgm and, when `panels`, panels/NNNNNN.jpg (of the undistorted image, as the
// detector saw it). `image` is the input image, `detector` the one that made `result`. False with
// a message naming the file on failure.
bool WriteFrameOutputs(const std::string& dir, int index, const cv::Mat& image,
                       const FrameResult& result, const ObstacleDetector& detector, bool panels,
                       std::string* error);

// Creates dir/labels, dir/height, dir/local, dir/panels.
bool CreateFrameOutputFolders(const std::string& dir, std::string* error);

}  // namespace monoplane::app
