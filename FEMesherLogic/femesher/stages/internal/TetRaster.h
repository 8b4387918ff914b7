// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file TetRaster.h
/// (Private to the logic library.) A labelled tet mesh sampled on a label map's grid, as the
/// Fidelity stage and `femesher quality --raster` need it:
///  - `rasterize`: the tet containing each voxel centre (the voxel-centre agreement);
///  - `overlapVolumes`: per label, the volume shared by that label's tets and its voxels (the
///    volume Dice). A voxel crossed by no interface or boundary triangle of the mesh lies in one
///    material region, which its centre tells; every other voxel is crossed by s x s lines
///    parallel to x (s = linesPerAxis, one at a random place in each cell of the voxel's y-z face)
///    and each tet gets the length of each line inside it, exactly: the overlap is exact along x,
///    stratified across, and exact in the voxels the mesh surface does not cut.
/// Containment of a sample point: all four barycentric coordinates > tol; a point on a face
/// belongs to the tet only when the face's outward normal is lexicographically positive
/// ("simulation of simplicity"), so in a conformal mesh every point is claimed by exactly one
/// tet. Threads own disjoint z-slabs of the grid: no races, results independent of threads.

#include <femesher/Types.h>

#include <cstdint>
#include <unordered_map>
#include <vector>

namespace femesher {

class RunContext;

/// Dense index of a label value (0 = background / no tet), via a table for compact ranges.
class LabelIndex {
 public:
  explicit LabelIndex(const std::vector<int32_t>& sorted);
  uint16_t operator()(int32_t l) const {
    if (!table_.empty()) return table_[size_t(int64_t(l) - lo_)];
    return map_.at(l);
  }
  size_t size() const { return ids_.size(); }
  int32_t label(size_t k) const { return ids_[k]; }

 private:
  std::vector<int32_t> ids_;
  int32_t lo_ = 0;
  std::vector<uint16_t> table_;
  std::unordered_map<int32_t, uint16_t> map_;
};

/// `tetValue[t]` at each voxel centre of `labels`' grid that lies in tet t, `background` where no
/// tet holds the centre.
std::vector<uint16_t> rasterize(const LabelVolume& labels, const TetMesh& mesh,
                                const std::vector<uint16_t>& tetValue, uint16_t background,
                                int threads, RunContext* ctx);

/// Per dense label index k: the volume (mm^3) of the intersection of the tets with
/// tetIndex == k and the voxels whose label has index k. `centre` is `rasterize`'s result with
/// the same indices, `tris` the mesh's extractInterfaces(). linesPerAxis >= 1. The lengths are
/// summed as integers (units of 2^-50 voxel): the result does not depend on the thread count.
std::vector<double> overlapVolumes(const LabelVolume& labels, const TetMesh& mesh,
                                   const std::vector<InterfaceTriangle>& tris,
                                   const LabelIndex& index, const std::vector<uint16_t>& tetIndex,
                                   const std::vector<uint16_t>& centre, int linesPerAxis,
                                   int threads, RunContext* ctx);

}  // namespace femesher
