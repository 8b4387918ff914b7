// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/DeferredCurving.h>
#include <femesher/Status.h>
#include <femesher/stages/InterfaceSmoothing.h>

#include <map>
#include <utility>

namespace femesher {

std::shared_ptr<const MidEdgePositions> curvePhysicalMidEdgeNodes(
    const TetMesh& canonical, const IndicatorField& field, double facetDistanceVoxels,
    const LabelVolume& frame, QuadraticCurvingResult& figures, RunContext& ctx) {
  const OptimizeInterfaces interfaces = indicatorInterfaces(field, facetDistanceVoxels);
  QuadraticCurvingResult r = curveMidEdgeNodes(canonical, interfaces, {}, ctx);
  auto nodes = std::make_shared<MidEdgePositions>();
  nodes->reserve(r.nodes.size());
  for (const auto& [key, p] : r.nodes) (*nodes)[key] = frame.canonicalToPhysical(p);
  r.nodes.clear();
  figures = std::move(r);
  return nodes;
}

std::shared_ptr<const MidEdgePositions> midEdgeNodesWithCopies(const MidEdgePositions& nodes,
                                                               const TetMesh& mesh,
                                                               size_t firstCopy) {
  const std::vector<Vec3>& points = mesh.points;
  std::map<Vec3, int32_t> originalAt;
  for (size_t i = 0; i < firstCopy && i < points.size(); ++i) originalAt.emplace(points[i], int32_t(i));
  std::vector<int32_t> original(points.size());
  for (size_t i = 0; i < points.size(); ++i)
    original[i] = i < firstCopy ? int32_t(i) : originalAt.at(points[i]);
  auto out = std::make_shared<MidEdgePositions>();
  for (const auto& t : mesh.tets)
    for (const auto& e : kTet10Edges) {
      const int32_t a = t[size_t(e[0])], b = t[size_t(e[1])];
      const auto it = nodes.find(tetEdgeKey(original[size_t(a)], original[size_t(b)]));
      if (it != nodes.end()) (*out)[tetEdgeKey(a, b)] = it->second;
    }
  return out;
}

DeferredCurving::DeferredCurving(PreprocessedVolume grid, std::unique_ptr<IndicatorField> field,
                                 TetMesh canonical, double facetDistanceVoxels,
                                 const LabelVolume& frame)
    : grid_(std::move(grid)),
      field_(std::move(field)),
      canonical_(std::move(canonical)),
      facetDistance_(facetDistanceVoxels) {
  if (!field_) throw Error(ErrorCode::Internal, "DeferredCurving: no indicator functions");
  field_->rebind(grid_);  // the field reads the grid it was computed on, now held here
  canonical_.points.shrink_to_fit();  // kept for a while: no spare capacity
  canonical_.tets.shrink_to_fit();
  canonical_.tetLabels.shrink_to_fit();
  frame_.dims = frame.dims;
  frame_.spacing = frame.spacing;
  frame_.origin = frame.origin;
  frame_.direction = frame.direction;
  frame_.sourcePath = frame.sourcePath;
}

std::shared_ptr<const MidEdgePositions> DeferredCurving::midEdgeNodes(const TetMesh& mesh,
                                                                      RunContext& ctx) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (nodes_) return nodes_;
  const size_t vertices = canonical_.points.size();
  if (mesh.points.size() < vertices)
    throw Error(ErrorCode::Internal, "DeferredCurving: not the mesh of this run");
  QuadraticCurvingResult figures;
  auto nodes = curvePhysicalMidEdgeNodes(canonical_, *field_, facetDistance_, frame_, figures, ctx);
  if (mesh.points.size() > vertices) nodes = midEdgeNodesWithCopies(*nodes, mesh, vertices);
  figures_ = std::move(figures);
  nodes_ = std::move(nodes);
  // The nodes are all a later call returns: what made them is not needed any more.
  field_.reset();
  grid_ = PreprocessedVolume{};
  canonical_ = TetMesh{};
  return nodes_;
}

QuadraticCurvingResult DeferredCurving::figures() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return figures_;
}

size_t DeferredCurving::memoryBytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  size_t n = (field_ ? field_->storedBytes() : 0) + grid_.labels.capacity() * sizeof(uint16_t) +
             canonical_.points.capacity() * sizeof(Vec3) +
             canonical_.tets.capacity() * sizeof(canonical_.tets[0]) +
             canonical_.tetLabels.capacity() * sizeof(int32_t);
  // A hash map's entry: key, position, next pointer, and about one bucket pointer.
  if (nodes_) n += nodes_->size() * (sizeof(MidEdgePositions::value_type) + 2 * sizeof(void*));
  return n;
}

}  // namespace femesher
