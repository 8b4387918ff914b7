// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file BoundaryMesh.h
/// Stage 8 ("Boundary Meshing"): 3-D Delaunay triangulation (CGAL) of all interface samples; each
/// tet is labelled by the material at its circumcentre (argmax of the indicator functions; the
/// centroid when the circumcentre leaves the grid), and every triangle between two tets of
/// different labels is an interface triangle marked with its label pair. The result is a
/// watertight, conformal multi-material surface that cannot self-intersect (all triangles are
/// faces of one triangulation): the restricted Delaunay surface of the samples.
///
/// Refinement (facet_distance > 0): interface triangles whose centroid is farther than the bound
/// from the interface get the interface point on their normal inserted (CGAL's facet_distance
/// criterion), so thin and strongly curved parts follow the labels.
///
/// Repair: a kept label that no tet carries (too small for the sampling) gets all its dense
/// interface samples and voxel centres inserted, and the labelling is redone (up to 3 rounds);
/// if it still has no tet, the tets containing its voxel centres take its label (reported).
/// All positions are in the canonical frame (mm).

#include <femesher/Types.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/SurfaceSampling.h>

#include <memory>
#include <utility>
#include <vector>

namespace femesher {

class RunContext;

/// The labelled Delaunay triangulation, kept for labelling the volume mesh (opaque).
class LabelledDelaunay {
 public:
  ~LabelledDelaunay();
  /// Compact label of the Delaunay tet containing a canonical point (0 outside the hull).
  int labelAt(const Vec3& canonical) const;
  /// Number of tets per compact label.
  std::vector<size_t> tetsPerLabel() const;
  /// For every input point (by its index in `points` of buildBoundaryMesh), the indices of the
  /// input points joined to it by a Delaunay edge (CSR: offsets has n+1 entries).
  void adjacency(size_t n, std::vector<uint32_t>& offsets, std::vector<uint32_t>& neighbours) const;
  /// For every compact label m (index m, 0..labels), one point inside each region that m's
  /// interface triangles enclose but that is not m (a cavity of another material, or of
  /// background, inside m): the hole points that make a tetrahedralisation of m's boundary alone
  /// hold m's tets only. A region is a connected set of tets of labels other than m (joined
  /// through faces that are not m's interface); those reaching the convex hull are not enclosed.
  /// Each point is the centroid of a tet of the region (strictly inside it). Canonical mm.
  /// Uses the tets' label slots as scratch space while it runs: do not call it concurrently with
  /// labelAt() or anything else reading the triangulation.
  std::vector<std::vector<Vec3>> enclosedHolePoints() const;
  /// The labelled tets themselves (label != 0), canonical coordinates, compact labels.
  void exportTets(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                  std::vector<int32_t>& labels) const;
  struct Impl;
  std::unique_ptr<Impl> impl;
};

enum class SurfaceMesher { RestrictedDelaunay, LocalDelaunay };
struct BoundaryMeshParameters {
  /// Surface approximation bound in voxels of the smallest spacing (CGAL's facet_distance);
  /// 0 = no refinement (which also turns off the voxel-centre pass).
  double facetDistance = 0.5;
  /// After the facet-distance refinement, insert interface points until every voxel centre
  /// next to another label lies in a tet of its own label.
  bool voxelRefinement = true;
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
  size_t junctionPoints = 0;        ///< points inserted so the triple lines become edges
  size_t junctionsOffLines = 0;     ///< junction particles still on no triple edge afterwards
};

/// `points`: the particles (local voxel index positions); a point within 0.002 voxel of the
/// input's box is put exactly on it (IndicatorField::snapToBox), and so is every refinement
/// point. `dense`: every interface vertex, used to repair labels that the particles miss. `facetDistance` (mm, 0 = off): refine the surface
/// until every interface triangle's centroid is within this distance of the interface f_a = f_b
/// (points inserted on the interface, farthest first, never closer than half the triangle's
/// shortest edge to another vertex; at most 10 rounds), then the voxel centres (each next to
/// another label must fall in a tet of its label), then, with `junctions` (whose particles must
/// be the first points), the triple lines: where a junction particle is on no edge of three
/// materials, either a material of its junction has no tet around it (its wedge at the line is
/// thinner than the sampling: points are inserted on the two interfaces bounding that wedge and
/// on the line, a voxel or less from the particle) or the line crosses its star off the edges
/// (line points are inserted next to it).
BoundarySurface buildBoundaryMesh(const IndicatorField& field, const std::vector<Vec3>& points,
                                  const SurfaceSamples& dense, RunContext& ctx,
                                  double facetDistance = 0, const Junctions* junctions = nullptr,
                                  bool voxelRefinement = true);

}  // namespace femesher
