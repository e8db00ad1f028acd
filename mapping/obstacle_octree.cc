#include "mapping/obstacle_octree.h"

#include <octomap/OcTree.h>

#include <map>
#include <sstream>
#include <utility>

namespace monoplane {

void ObstacleOctree::Options::Describe(OptionVisitor& v) {
  using R = OptionRange;
  // OctoMap's 16-level keys span +-2^15 voxels: at 1 cm that is +-328 m; finer ones also make a
  // run's tree grow without bound.
  v.Real("resolution_m", &resolution_m, R::Closed(0.01, 1), "OctoMap voxel side, m");
  v.Real("max_range_m", &max_range_m, R::Above(0), "longest ray inserted into the OctoMap, m");
  v.Real("prob_hit", &prob_hit, R::Open(0.5, 1), "OctoMap's hit probability");
  v.Real("prob_miss", &prob_miss, R::Open(0, 0.5), "OctoMap's miss probability");
  v.Integer("free_ray_stride", &free_ray_stride, R::AtLeast(1),
            "free space carved along every N-th occupied voxel column");
}

bool ObstacleOctree::Options::IsValid(std::string* error) const {
  return CheckOptions(*this, "octree", error);
}

struct ObstacleOctree::Impl {
  Options options;
  octomap::OcTree tree;
  explicit Impl(const Options& o) : options(o), tree(o.resolution_m) {
    tree.setProbHit(o.prob_hit);
    tree.setProbMiss(o.prob_miss);
  }
};

ObstacleOctree::ObstacleOctree(const Options& options)
    : impl_(std::make_unique<Impl>(ValidOrDie(options, "ObstacleOctree"))) {}
ObstacleOctree::~ObstacleOctree() = default;
ObstacleOctree::ObstacleOctree(ObstacleOctree&&) noexcept = default;
ObstacleOctree& ObstacleOctree::operator=(ObstacleOctree&&) noexcept = default;

void ObstacleOctree::Insert(const std::vector<Eigen::Vector3f>& points_in_base,
                            const Pose2& map_from_base,
                            const Eigen::Vector3d& camera_centre_in_base) {
  if (points_in_base.empty()) return;
  const double c = std::cos(map_from_base.yaw), s = std::sin(map_from_base.yaw);
  auto to_map = [&](double x, double y, double z) {
    return octomap::point3d(static_cast<float>(c * x - s * y + map_from_base.x),
                            static_cast<float>(s * x + c * y + map_from_base.y),
                            static_cast<float>(z));
  };
  const octomap::point3d origin =
      to_map(camera_centre_in_base.x(), camera_centre_in_base.y(), camera_centre_in_base.z());
  octomap::OcTree& tree = impl_->tree;
  // As OccupancyOcTreeBase::computeUpdate with discretisation: each voxel gets at most one update
  // per insertion, hits win over misses.
  octomap::KeySet occupied, free;
  octomap::KeyRay ray;
  const double max_range = impl_->options.max_range_m;
  std::map<std::pair<octomap::key_type, octomap::key_type>, octomap::point3d> column_tops;
  for (const Eigen::Vector3f& p : points_in_base) {
    const octomap::point3d end = to_map(p.x(), p.y(), p.z());
    if ((end - origin).norm() > max_range) continue;
    octomap::OcTreeKey key;
    if (!tree.coordToKeyChecked(end, key)) continue;
    occupied.insert(key);
    auto [it, inserted] = column_tops.emplace(std::make_pair(key[0], key[1]), end);
    if (!inserted && end.z() > it->second.z()) it->second = end;
  }
  std::size_t column = 0;
  for (const auto& [xy, end] : column_tops) {
    if (column++ % static_cast<std::size_t>(impl_->options.free_ray_stride) != 0) continue;
    if (tree.computeRayKeys(origin, end, ray)) free.insert(ray.begin(), ray.end());
  }
  for (const octomap::OcTreeKey& key : free) {
    if (!occupied.count(key)) tree.updateNode(key, false);
  }
  for (const octomap::OcTreeKey& key : occupied) tree.updateNode(key, true);
}

std::string OctomapBinaryHeader(const std::string& tree_type, std::size_t num_nodes,
                                double resolution_m) {
  std::ostringstream out;
  out << "# Octomap OcTree binary file"  // AbstractOccupancyOcTree::binaryFileHeader (protected)
      << "\n# (feel free to add / change comments, but leave the first line as it is!)\n#\n"
      << "id " << tree_type << std::endl
      << "size " << num_nodes << std::endl
      << "res " << resolution_m << std::endl
      << "data" << std::endl;
  return out.str();
}

void ObstacleOctree::Clear() { impl_->tree.clear(); }

std::string ObstacleOctree::ToBinary() const {
  std::ostringstream out;
  // The .bt format of OcTree::writeBinaryConst (which, unlike writeBinary, does not prune the live
  // tree to its maximum-likelihood values and so change later updates): its header, then the
  // nodes from the root. Written here because writeBinaryConst prints " done." on stderr.
  const octomap::OcTree& tree = impl_->tree;
  out << OctomapBinaryHeader(tree.getTreeType(), tree.size(), tree.getResolution());
  if (tree.getRoot() != nullptr) tree.writeBinaryNode(out, tree.getRoot());
  return out.str();
}

std::size_t ObstacleOctree::NumOccupiedLeaves() const {
  std::size_t n = 0;
  for (auto it = impl_->tree.begin_leafs(); it != impl_->tree.end_leafs(); ++it) {
    if (impl_->tree.isNodeOccupied(*it)) ++n;
  }
  return n;
}

}  // namespace monoplane
