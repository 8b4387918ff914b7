// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelledDelaunay.h
/// The labelled Delaunay triangulation under stage 8 (boundary meshing): the 3-D Delaunay
/// triangulation (CGAL) of the interface points, each tet labelled by the material at its
/// circumcentre (argmax of the indicator functions; the centroid when the circumcentre leaves the
/// grid or the tet is flat). Every triangle between two tets of different labels is an interface
/// triangle: together they are the restricted Delaunay surface of the points, watertight,
/// conformal and free of self-intersections. SurfaceRefinement.h inserts points into it;
/// BoundaryMesh.h builds it and extracts the surface; VolumeMesh reads its labels.
///
/// All positions are in the canonical frame (index x spacing, mm); labels are compact material
/// ids (0 = outside). Deterministic: the same points give the same triangulation, the same labels
/// and the same surface, whatever the thread count and the heap layout.

#include <femesher/Types.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace femesher {

class IndicatorField;
class RunContext;

class LabelledDelaunay {
 public:
  /// An empty triangulation for compact labels 0..labels.
  explicit LabelledDelaunay(int labels);
  ~LabelledDelaunay();
  LabelledDelaunay(const LabelledDelaunay&) = delete;
  LabelledDelaunay& operator=(const LabelledDelaunay&) = delete;

  /// Inserts canonical points (mm) at once (CGAL's spatial sort, reseeded so the same points give
  /// the same triangulation); the vertex of points[i] remembers i (see adjacency()). A point equal
  /// to one already there adds no vertex. New tets are unlabelled until label() runs.
  void insert(const std::vector<Vec3>& points);
  /// Inserts further points one by one, marked as no input point (repair points: adjacency()
  /// leaves them out). New tets are unlabelled until label() runs.
  void insertRepairPoints(const std::vector<Vec3>& points);
  /// Labels every tet from the indicator functions (multi-threaded; cancel checked: throws the
  /// Canceled error of RunContext::checkCancel).
  void label(const IndicatorField& field, RunContext& ctx);
  /// Gives label m to the finite tet containing a canonical point; false when the point is outside
  /// the hull (nothing changes then).
  bool forceLabelAt(const Vec3& canonical, int m);

  /// Number of vertices (input, refinement and repair points).
  size_t vertexCount() const;
  /// Number of finite tets.
  size_t tetCount() const;
  /// Compact label of the Delaunay tet containing a canonical point (0 outside the hull).
  int labelAt(const Vec3& canonical) const;
  /// Number of tets per compact label (labels + 1 entries).
  std::vector<size_t> tetsPerLabel() const;
  /// For every input point (by its index in the points given to insert()), the indices of the
  /// input points joined to it by a Delaunay edge (CSR: offsets has n+1 entries). Points with an
  /// index >= n, and refinement and repair points, are left out.
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
  /// The same cavities, each with up to `candidates` points: the hole point above first, then
  /// the centroids of the cavity's largest tets (for a surface other than the restricted
  /// Delaunay one, which may bound a cavity a little differently: VolumeMesh takes the first
  /// point that lies outside the material's own surface).
  std::vector<std::vector<std::vector<Vec3>>> enclosedCavities(size_t candidates = 1) const;
  /// The labelled tets themselves (label != 0), canonical coordinates, compact labels.
  void exportTets(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                  std::vector<int32_t>& labels) const;
  /// The interface triangles (faces between tets of different labels, the outside included).
  /// `points`: the vertices they use, sorted by position (x, then y, then z); `triangles` index
  /// them, sorted by label pair and then by sorted vertex ids; each triangle's normal points from
  /// the lower label (`pairs[t].first`) into the higher one (`pairs[t].second`).
  void interfaceTriangles(std::vector<Vec3>& points, std::vector<std::array<int32_t, 3>>& triangles,
                          std::vector<std::pair<uint16_t, uint16_t>>& pairs) const;

  struct Impl;  ///< the CGAL triangulation (stages/internal/LabelledDelaunayImpl.h)
  std::unique_ptr<Impl> impl;
};

}  // namespace femesher
