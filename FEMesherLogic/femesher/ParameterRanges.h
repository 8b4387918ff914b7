// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file ParameterRanges.h
/// The admissible range of every size-like parameter, derived from the label map it is used on.
///
/// The fixed ranges of `parameterDescriptors()` cannot know the volume: `max_tet_volume=1e-9`
/// on a small ball asks TetGen for about 1e12 tets (it runs for hours), `target_edge_length=1e-9`
/// makes the surface stages sample at a billionth of a millimetre (TetGen's child crashed).
/// `checkSizeParameters` estimates the element count a value implies and refuses, before any
/// stage runs, a value that implies more than `kMaxEstimatedTets` or that is below a small
/// fraction of the smallest voxel spacing (detail no label map holds):
///
///  - target_edge_length (when > 0), edge_length_factor (when target_edge_length is 0) and h_max
///    (when > 0): the uniform edge length h they give must be >= max(kLengthFloorVoxels x the
///    smallest spacing, the h at which tets = kMaxEstimatedTets). Estimate: tets = meshed volume
///    / (h^3 / (6 sqrt 2)), the volume of a regular tet of edge h; the meshed volume is the
///    number of voxels of a material (not background 0) x the voxel volume.
///  - h_min (when > 0): >= kLengthFloorVoxels x the smallest spacing (a lower clamp of the
///    adaptive size, so not a typical size; h_max and the uniform size bound the count).
///  - max_tet_volume (when > 0): meshed volume / max_tet_volume <= kMaxEstimatedTets (every tet
///    is at most that large, so this is a lower bound of the count) and >= the volume of a
///    regular tet of edge kLengthFloorVoxels x the smallest spacing.
///  - facet_distance (voxels, when > 0): >= kFacetDistanceFloorVoxels.
///
/// `MeshingRun` calls it before any stage, so `femesher mesh`, `optimize`, `sizing`,
/// `medial-axis` and the panel all refuse the same values the same way (InvalidArgument: exit 2).

#include <femesher/Parameters.h>
#include <femesher/Status.h>
#include <femesher/Types.h>

namespace femesher {

/// The element-count ceiling of the estimate (tets).
constexpr double kMaxEstimatedTets = 50e6;
/// Smallest length parameter, as a fraction of the smallest voxel spacing.
constexpr double kLengthFloorVoxels = 0.1;
/// Smallest facet_distance other than 0 (voxels of the smallest spacing).
constexpr double kFacetDistanceFloorVoxels = 0.02;

/// What the estimate works from: the meshed volume and the voxel spacings.
struct VolumeExtent {
  double meshedVolume = 0;   ///< mm^3: voxels of a material x the voxel volume
  double smallestSpacing = 0, meanSpacing = 0;  ///< mm
};
VolumeExtent volumeExtent(const LabelVolume& volume);

/// Tets of a mesh of edge length `h` (mm) filling `meshedVolume` (mm^3): volume / (h^3/(6 sqrt 2)).
double estimatedTets(double meshedVolume, double h);

/// InvalidArgument naming the parameter, its value, the allowed range and why (the estimated
/// count, the smallest useful value for this volume), or ok. See the file comment.
Status checkSizeParameters(const MeshingParameters& params, const LabelVolume& volume);

}  // namespace femesher
