// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Fidelity.h
/// Agreement of a mesh with the label map it came from.
///  - Per material: voxel volume, mesh volume, relative volume error, and the volume Dice
///    2|M∩L| / (|M|+|L|) of the material's tets M and its voxels L (each voxel a box of the voxel
///    size): the overlap is exact in voxels that no mesh triangle crosses; in the others it is
///    integrated exactly along 5 x 5 lines parallel to x per voxel, stratified in y and z (on the
///    knee every label's Dice within 0.0006 of the converged value; 4 x 4 x 4 points were within
///    0.0014).
///  - The voxel-centre agreement, a second figure: over all voxel centres, the voxel's label
///    against the label of the tet that contains the centre. It is not a volume measure (a
///    surface passing through every boundary voxel's centre scores 1 while thin layers lose
///    volume), kept because it says where mesh and labels disagree (`--raster`).
///  - Boundary distance, in voxels (of the smallest spacing): mesh->labels = distance from points
///    sampled on the mesh's interface triangles to the nearest voxel boundary face between two
///    different labels; labels->mesh = from voxel boundary face centres to the nearest mesh
///    interface triangle. Mean, median, 95th and 99th percentile, max.
///  - Missing labels: labels of the input that no tet carries.

#include <femesher/Types.h>

#include <string>
#include <vector>

namespace femesher {

class RunContext;

struct MaterialFidelity {
  int32_t label = 0;
  std::string name;
  size_t voxels = 0;          ///< voxels of this label in the input
  size_t meshVoxels = 0;      ///< voxel centres falling in tets of this label
  double voxelVolume = 0;     ///< mm^3
  double meshVolume = 0;      ///< mm^3, sum of tet volumes
  double volumeError = 0;     ///< (mesh - voxel) / voxel
  double overlapVolume = 0;   ///< mm^3 shared by the material's tets and its voxels
  double dice = 0;            ///< volume Dice 2 overlap / (voxelVolume + meshVolume)
  double voxelCentreDice = 0; ///< voxel-centre agreement (see the file comment)
  size_t tets = 0;
};

struct DistanceStats {
  size_t samples = 0;     ///< distances evaluated
  size_t population = 0;  ///< candidate samples before subsampling
  bool sampled = false;   ///< true when a deterministic stride subsample was used
  double mean = 0, median = 0, p95 = 0, p99 = 0, max = 0;  ///< in voxels
};

struct FidelityReport {
  std::vector<MaterialFidelity> materials;  ///< every non-background input label, sorted
  std::vector<int32_t> missingLabels;       ///< input labels absent from the mesh
  DistanceStats meshToLabels, labelsToMesh;
  double voxelSize = 1;                     ///< mm, the unit of the distances (min spacing)
};

/// `labels` is the input label map (LPS geometry), `mesh` in LPS. `ctx` may be null.
FidelityReport computeFidelity(const LabelVolume& labels, const TetMesh& mesh, RunContext& ctx);

/// The mesh sampled on the voxel centres of `grid` (same geometry): each voxel gets the label of
/// the tet containing its centre, 0 where no tet does (the rule Dice uses). Write it next to the
/// input to see where mesh and labels disagree (`femesher quality MESH --labels IN --raster OUT`).
LabelVolume rasterizeMesh(const LabelVolume& grid, const TetMesh& mesh, RunContext* ctx = nullptr);

std::string fidelityReportToJson(const FidelityReport& report);
std::string fidelityReportToText(const FidelityReport& report);

}  // namespace femesher
