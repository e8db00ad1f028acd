#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "perception/frame_types.h"

namespace monoplane::app {

// Writes the per-frame outputs of ../shared/INTERFACES.md for frame `index` under `dir`:
// labels/NNNNNN.png, height/NNNNNN.png, local/NNNNNN.yaml + .pgm and, when `panels`,
// panels/NNNNNN.jpg. Creates the folders. False with a message naming the file on failure.
bool WriteFrameOutputs(const std::string& dir, int index, const cv::Mat& image,
                       const FrameResult& result, bool panels, std::string* error);

// Creates dir/labels, dir/height, dir/local, dir/panels.
bool CreateFrameOutputFolders(const std::string& dir, std::string* error);

}  // namespace monoplane::app
