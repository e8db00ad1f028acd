#ifndef MONOPLANE_PERCEPTION_CONNECTED_REGIONS_H_
#define MONOPLANE_PERCEPTION_CONNECTED_REGIONS_H_

#include <opencv2/imgproc.hpp>

namespace monoplane {

// cv::connectedComponentsWithStats of an 8-bit mask, 8-connected, CV_32S labels, by Grana's
// block-based algorithm (CCL_GRANA): the same labels (raster order), statistics and centroids as
// OpenCV's default (Spaghetti), which on one thread (the run sets cv::setNumThreads(1)) takes
// about three times as long in OpenCV 4.6 (0.5 against 0.16 ms on a 320 x 240 mask, even an empty
// one). Returns the number of labels, the background's included.
inline int ConnectedRegions(const cv::Mat& mask, cv::Mat* labels, cv::Mat* stats,
                            cv::Mat* centroids) {
  return cv::connectedComponentsWithStats(mask, *labels, *stats, *centroids, 8, CV_32S,
                                          cv::CCL_GRANA);
}

}  // namespace monoplane

#endif  // MONOPLANE_PERCEPTION_CONNECTED_REGIONS_H_
