#pragma once

#include <opencv2/core.hpp>

#include "perception/frame_types.h"

namespace monoplane {

// The 2x2 picture for people: input with labels, segmentation, zero disparity, top view.
cv::Mat RenderPanels(const cv::Mat& current, const FrameResult& result);

// The local map drawn as an image (free white, occupied black, unknown grey, x up).
cv::Mat RenderLocalMap(const OccupancyGrid& grid, int pixels_per_cell = 2);

}  // namespace monoplane
