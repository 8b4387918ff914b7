// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file VolumeMesh.h
/// Stage 9 ("Volume Meshing"): TetGen 1.5 on the multi-material interface surface.
/// By default each material is meshed on its own (its interface triangles, holes in the cavities
/// of other materials it encloses), several TetGen runs side by side in child processes; the
/// runs share the unsplit interface triangles, so the result is one conformal mesh. Otherwise, or
/// if a run fails: the whole surface at once.
/// Input PLC: the interface triangles (each shared triangle once, facet marker = interface id);
/// switches p (PLC), q (radius-edge / min dihedral bound), A (region attributes: TetGen numbers
/// the enclosed regions itself), Y (no Steiner points on the interfaces, so they stay exactly the
/// sampled surface and conformal), O (optimisation), a (max volume, when set), Q (quiet).
/// Each region gets the material of the labelled Delaunay tets it lies in (volume-weighted vote);
/// enclosed background cavities are dropped. TetGen's thrown int is caught and mapped to a
/// message; on failure the stage retries without Y, and as a last resort returns the labelled
/// Delaunay tets themselves (each fallback is reported as a warning).

#include <femesher/Types.h>
#include <femesher/stages/BoundaryMesh.h>

#include <memory>
#include <string>
#include <vector>

namespace femesher {

class RunContext;

struct VolumeMeshParameters {
  double maxRadiusEdgeRatio = 3.0;  ///< 0 = no quality refinement; below about 1.2 TetGen may not terminate
  /// degrees (TetGen's -q ratio/angle). 3: TetGen only breaks the flattest tets and leaves the
  /// rest to Optimize, which fixes slivers without adding interior points; 12 gave 11-26 % more
  /// tets on the shared volumes at the same worst angle after Optimize.
  double minDihedralAngle = 3.0;
  double maxTetVolume = 0;          ///< mm^3, 0 = none
  bool preserveInterfaces = true;   ///< -Y
  int optimizationLevel = 3;
  /// Target edge length (mm) at each surface point, handed to TetGen as point metrics (-m) so the
  /// interior follows the sizing field; empty = none.
  std::vector<double> pointSizes;
  bool usePointSizes = true;
  /// With preserveInterfaces: mesh each material's closed boundary in its own TetGen run (up to
  /// RunContext::threads() at a time, each in a child process; cavities of other materials are
  /// holes). The interface triangles are not split, so the pieces share them exactly. If a run
  /// fails, the whole surface is meshed at once as below.
  bool perMaterial = true;
};

struct VolumeMeshResult {
  /// Canonical-frame mesh with *compact* labels (converted by the pipeline); from TetGen, points
  /// and tets come in spatial (Morton) order.
  std::vector<Vec3> points;
  std::vector<std::array<int32_t, 4>> tets;
  std::vector<int32_t> labels;
  std::string switches;          ///< TetGen switches actually used ("" for the Delaunay fallback)
  std::string method;            ///< "tetgen", "tetgen-without-Y" or "delaunay-fallback"
  size_t regions = 0, droppedCavityTets = 0;
  size_t tetgenRuns = 0;   ///< TetGen problems solved (one per material, or 1)
  size_t holePoints = 0;   ///< cavity points handed to the per-material runs
};

/// Report figures: tetgen_regions, tetgen_runs, tetgen_hole_points.
ReportCounts reportCounts(const VolumeMeshResult& result);

/// Reads surface.delaunay (the labelled Delaunay: the per-material runs' hole points, the
/// fallbacks' labels), which the surface keeps.
VolumeMeshResult buildVolumeMesh(const BoundarySurface& surface, const VolumeMeshParameters& params,
                                 RunContext& ctx);
/// The same with the labelled Delaunay handed over (normally surface.delaunay, moved out of it;
/// surface.delaunay is not read): the triangulation is released as soon as the per-material
/// problems have their hole points, before TetGen runs, and the fallbacks read a compact copy of
/// its labelled tets (the run's memory beside the TetGen helpers: colin27's triangulation held
/// 420 MB of the main process's 710 MB at this stage).
VolumeMeshResult buildVolumeMesh(const BoundarySurface& surface,
                                 std::shared_ptr<LabelledDelaunay> delaunay,
                                 const VolumeMeshParameters& params, RunContext& ctx);

}  // namespace femesher
