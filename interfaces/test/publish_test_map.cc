// Test program for `monoplane echo`: publishes a known 40 x 30 map (transient-local) and a pose on
// a domain, then stays until a reader of rt/map has come and gone, or 30 s passed.
// Usage: publish_test_map DOMAIN
#include <cstdio>
#include <cstdlib>
#include <string>

#include "interfaces/map_publisher.h"

int main(int argc, char** argv) {
  using namespace monoplane;
  using namespace monoplane::interfaces;
  if (argc != 2) {
    std::fprintf(stderr, "usage: publish_test_map DOMAIN\n");
    return 2;
  }
  MapPublisher::Options options;
  options.domain_id = std::atoi(argv[1]);
  std::string error;
  auto publisher = MapPublisher::Create(options, &error);
  if (!publisher) {
    std::fprintf(stderr, "publish_test_map: %s\n", error.c_str());
    return 1;
  }
  GridGeometry g;
  g.resolution_m = 0.05;
  g.origin_x_m = -1.0;
  g.origin_y_m = -0.75;
  g.width = 40;
  g.height = 30;
  OccupancyGrid grid(g, kCellUnknown);
  for (int col = 0; col < 40; ++col) grid.At(col, 0) = kCellOccupied;  // 40 occupied
  for (int row = 1; row < 11; ++row) {
    for (int col = 0; col < 40; ++col) grid.At(col, row) = kCellFree;  // 400 free
  }
  if (publisher->PublishMap(grid, 42 * 1000000000LL + 5, &error) != PublishStatus::kSent) {
    std::fprintf(stderr, "publish_test_map: %s\n", error.c_str());
    return 1;
  }
  // Stay until a reader has come and gone (the echo under test), at most 30 s.
  if (!publisher->WaitForReaders(
          MapPublisher::Topic::kMap, [](int n) { return n > 0; }, 30.0))
    return 1;
  return publisher->WaitForReaders(
             MapPublisher::Topic::kMap, [](int n) { return n == 0; }, 30.0)
             ? 0
             : 1;
}
