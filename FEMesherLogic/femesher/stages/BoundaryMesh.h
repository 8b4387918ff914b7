// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file BoundaryMesh.h
/// Stage 8 ("Boundary Meshing"): 3-D Delaunay triangulation (CGAL) of all interface samples; each
/// tet is labelled by the material at its circumcentre (argmax of the indicator functions; the
/// centroid when the circumcentre leaves the grid), and every triangle between two tets of
/// different labels is an interface triangle marked with its label pair. The result is a
/// watertight, conformal multi-material surface that cannot self-intersect (all triangles are
/// faces of one triangulation): the restricted Delaunay surface of the samples
/// (LabelledDelaunay.h).
///
/// Refinement (facetDistance > 0, SurfaceRefinement.h): interface triangles whose centroid is
/// farther than the bound from the interface get the interface point on their normal inserted
/// (CGAL's facet_distance criterion), so thin and strongly curved parts follow the labels; then
/// the voxel centres next to another label, then the triple lines.
///
/// Repair: a kept label that no tet carries (too small for the sampling) gets all its dense
/// interface samples and voxel centres inserted, and the labelling is redone (up to 3 rounds);
/// if it still has no tet, the tets containing its voxel centres take its label (reported).
///
/// buildInterfaceSurface() is the whole stage as the pipeline runs it: the restricted Delaunay
/// surface, or the local Delaunay one (LocalDelaunay.h) with the restricted one as fallback.
/// All positions are in the canonical frame (mm) unless said otherwise.

#include <femesher/Types.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelledDelaunay.h>
#include <femesher/stages/LocalDelaunay.h>
#include <femesher/stages/ParticleSystem.h>
#include <femesher/stages/SurfaceRefinement.h>
#include <femesher/stages/SurfaceSampling.h>

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

class RunContext;

enum class SurfaceMesher { RestrictedDelaunay, LocalDelaunay };

struct BoundaryMeshParameters {
  /// Surface approximation bound in voxels of the smallest spacing (CGAL's facet_distance);
  /// 0 = no refinement (which also turns off the voxel-centre pass).
  double facetDistance = 0.5;
  /// After the facet-distance refinement, insert interface points until every voxel centre
  /// next to another label lies in a tet of its own label.
  bool voxelRefinement = true;
  /// After the facet-distance refinement, needle-shaped interface triangles larger than the
  /// target size get points (refineFacetShape; the `facet_angle` parameter). Off (0 degrees) by
  /// default: it mends thin plates and small shapes sampled coarsely (the one-voxel plate's worst
  /// tet 3.5 -> 15 degrees), but on the shared label maps it only moves the worst tet Optimize
  /// leaves, either way (example_seg 11.3 -> 6.5, digimouse 11.9 -> 14.5 degrees). Needs `sizeAt`.
  FacetShapeCriteria facetShape{0.0, 1.5};
  /// The target edge length at a canonical point (mm); empty = no facet-shape refinement.
  std::function<double(const Vec3&)> sizeAt;
  /// The surface handed on: the restricted Delaunay surface, or the local Delaunay one built
  /// from the particles (buildInterfaceSurface only; buildBoundaryMesh ignores it).
  SurfaceMesher mesher = SurfaceMesher::RestrictedDelaunay;
};

struct BoundarySurface {
  std::vector<Vec3> points;  ///< canonical mm; only vertices used by interface triangles
  std::vector<std::array<int32_t, 3>> triangles;
  std::vector<std::pair<uint16_t, uint16_t>> trianglePairs;  ///< compact labels, first < second
  std::shared_ptr<LabelledDelaunay> delaunay;
  size_t delaunayVertices = 0, delaunayTets = 0;
  std::vector<int> repairedLabels;  ///< compact labels that needed extra points
  std::vector<int> forcedLabels;    ///< compact labels given to the tets holding their voxels
  size_t refinementPoints = 0;      ///< points inserted by the facet-distance refinement
  size_t voxelCentrePoints = 0;     ///< points inserted so voxel centres fall in their label
  size_t shapePoints = 0;           ///< points inserted to split needle triangles
  size_t junctionPoints = 0;        ///< points inserted so the triple lines become edges
  size_t junctionsOffLines = 0;     ///< junction particles still on no triple edge afterwards
  /// The triangles are the labelled Delaunay's own interface triangles (false once the local
  /// Delaunay surface replaced them): its regions' points then lie exactly outside or inside.
  bool fromDelaunay = true;
};

/// The restricted Delaunay surface of `points` (the particles, local voxel index positions; a
/// point within 0.002 voxel of the input's box is put exactly on it, IndicatorField::snapToBox,
/// and so is every refinement point). With fewer than 4 points every interface vertex of `dense`
/// is used instead; `dense` also repairs labels that the points miss.
/// With params.facetDistance > 0 (converted to mm with the field's smallest spacing) the surface
/// is refined until every interface triangle's centroid is within that distance of the
/// interface f_a = f_b (points inserted on the interface, farthest first, never closer than half
/// the triangle's shortest edge to another vertex; at most 10 rounds), then, with
/// params.sizeAt and params.facetShape.minAngleDegrees > 0, the needle triangles
/// (refineFacetShape), then, with params.voxelRefinement, the voxel centres (each next to another label must fall in a tet of
/// its label), then, with `junctions` (whose particles must be the first points; may be null),
/// the triple lines (refineJunctionEdges). Triangles are oriented from first into second label
/// and sorted (LabelledDelaunay::interfaceTriangles).
/// Throws Error(MeshingFailed) when there are fewer than 4 points and 4 dense samples, the
/// Canceled error when ctx is canceled. Reports progress 0.4 to 1.0 of the current stage.
BoundarySurface buildBoundaryMesh(const IndicatorField& field, const std::vector<Vec3>& points,
                                  const SurfaceSamples& dense, const Junctions* junctions,
                                  const BoundaryMeshParameters& params, RunContext& ctx);

/// The interface surface the volume mesher gets, and how it was made.
struct InterfaceSurface {
  /// The restricted Delaunay surface; when ldtUsed, its points, triangles and trianglePairs are
  /// the local Delaunay surface's (only the particles its triangles use, in order of first use),
  /// the rest (Delaunay triangulation, counts, repaired labels) stays the restricted one's.
  BoundarySurface surface;
  LocalDelaunayResult ldt;  ///< empty unless the local Delaunay mesher was asked for
  bool ldtUsed = false;     ///< the local Delaunay surface was watertight and is `surface`
  /// Share of the junction particles that are vertices of an edge shared by the triangles of
  /// three or more materials in the restricted Delaunay surface (1 without junction particles).
  double junctionShare = 0;
  /// Wall seconds of the restricted Delaunay surface (with its refinements and repair) and of
  /// the local Delaunay one (0 when not asked for).
  double restrictedSeconds = 0, ldtSeconds = 0;
};

/// The whole stage: the particles (local voxel index positions, junction particles first) put on
/// the input's box where within 0.002 voxel of it, their restricted Delaunay surface with
/// params' refinements (buildBoundaryMesh) and its junction share; with params.mesher ==
/// LocalDelaunay, the local Delaunay surface of the same particles (buildLocalDelaunaySurface,
/// default parameters, on the restricted Delaunay surface of the particles alone when the
/// refinements inserted points), used when it has no open edge and no self-intersection, else a
/// warning and the restricted surface. `systemParticles`: the particle system's particles, in the
/// order of `particles` (junction particles carry their label sets); when empty (the particle
/// system did not run), the junction particles then the selected samples stand in, and
/// `particles` must be their positions in that order. Warns (ctx) about labels that had to be
/// repaired or forced. Throws as buildBoundaryMesh.
InterfaceSurface buildInterfaceSurface(const IndicatorField& field, std::vector<Vec3> particles,
                                       const std::vector<Particle>& systemParticles,
                                       const SurfaceSamples& samples, const Junctions& junctions,
                                       const BoundaryMeshParameters& params, RunContext& ctx);

/// Order-sensitive checksum of a surface's points (to a micrometre) and triangles, for
/// determinism checks (an integer below 1e9+7, as a double).
double surfaceChecksum(const BoundarySurface& surface);

/// The run report's counts of the stage, in report order: delaunay_vertices, delaunay_tets,
/// surface_vertices, surface_triangles, surface_checksum, junction_particles_on_triple_edges,
/// surface_open_edges, surface_refinement_points, voxel_centre_refinement_points,
/// junction_refinement_points, then the ldt_* counts (open edges, holes, provenance,
/// self-intersections, triple-line links) and ldt_used (1 or 0).
std::vector<std::pair<std::string, double>> reportCounts(const InterfaceSurface& surface);

}  // namespace femesher
