// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file SurfaceSampling.h
/// Stages 3 ("Isosurface") and the first, simple form of stage 7: sample every material interface.
///
/// Isosurface: VTK's discrete flying edges (marching cubes on the label grid) finds every grid edge
/// that crosses an interface; each of its vertices is moved along its edge onto the smooth
/// interface f_a = f_b of the indicator functions (exact for the trilinear field) and kept only
/// where a and b are the two leading materials. The triangles serve as the preview surface.
///
/// Sampling: a Poisson-disk selection of those vertices with minimum distance
/// 0.75 x target edge length (or sizing field) per interface (and 0.3 x between different
/// interfaces), junction
/// neighbourhoods (cells with 3 or more labels) first, in a seeded order so the result is
/// deterministic. The particle system (later) replaces this selection.

#include <femesher/Types.h>
#include <femesher/stages/IndicatorFunctions.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

namespace femesher {

class RunContext;

struct SurfaceSample {
  Vec3 local;              ///< local voxel index position on the interface
  uint16_t a = 0, b = 0;   ///< compact labels, a < b
  bool junction = false;   ///< near a triple line (>= 3 labels around)
};

struct SurfaceSamplingParameters {
  double targetEdgeLength = 2.0;  ///< mm (resolved, > 0), used when `sizing` is empty
  /// Target edge length (mm) at a canonical position; when set, the Poisson-disk radius follows
  /// it: two samples of one interface keep 0.75 x the mean of their two sizes apart.
  std::function<double(const Vec3&)> sizing;
  uint64_t seed = 1;
};

struct SurfaceSamples {
  std::vector<SurfaceSample> all;       ///< every interface vertex (the dense candidate set)
  std::vector<uint32_t> selected;       ///< indices into `all` chosen at the target spacing
  size_t isosurfaceTriangles = 0;
};

/// Report figures: isosurface_triangles, interface_candidates, surface_samples.
ReportCounts reportCounts(const SurfaceSamples& samples);

/// `input` is only used to send previews in LPS.
SurfaceSamples sampleInterfaces(const IndicatorField& field, const LabelVolume& input,
                                const SurfaceSamplingParameters& params, RunContext& ctx);

}  // namespace femesher
