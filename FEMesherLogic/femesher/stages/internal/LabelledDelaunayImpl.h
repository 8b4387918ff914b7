// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelledDelaunayImpl.h
/// Private to the logic library (CGAL types): the triangulation behind LabelledDelaunay and the
/// point-insertion helpers that LabelledDelaunay.cxx and SurfaceRefinement.cxx share. Include it
/// from logic-library .cxx files only.

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelledDelaunay.h>

#include <cstdint>
#include <vector>

namespace femesher {

namespace internal {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
/// Vertex info: the index of the input point (>= 0), kRefinementPoint or kRepairPoint.
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int32_t, K>;
/// Cell info: the compact label of the tet (0 = outside and the infinite cells).
using Cb = CGAL::Triangulation_cell_base_with_info_3<int32_t, K>;
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
using Delaunay = CGAL::Delaunay_triangulation_3<K, Tds>;
using Point = K::Point_3;

/// Vertex info of a point inserted by a surface refinement.
constexpr int32_t kRefinementPoint = -2;
/// Vertex info of a point inserted to repair a label that no tet carries.
constexpr int32_t kRepairPoint = -1;

/// Label of cell c: the argmax of the indicator functions at its circumcentre, or at its centroid
/// when the circumcentre leaves the grid or the cell is flat; 0 for an infinite cell.
int labelCell(const IndicatorField& field, const Delaunay& dt, Delaunay::Cell_handle c);

/// Labels the cells created by inserting `fresh`: they are the cells incident to the new
/// vertices (a cell made by one insertion and destroyed by a later one is replaced by cells of
/// the later vertex).
void relabelAround(const IndicatorField& field, Delaunay& dt,
                   const std::vector<Delaunay::Vertex_handle>& fresh, int threads);

/// A point to insert on an interface (canonical mm): how far off the surface was there (the
/// order: farthest first; 0 = no point) and how close another vertex may be (mm).
struct Candidate {
  double deviation;
  Vec3 point;
  double exclusion;
};

/// Inserts the candidates with a non-zero deviation greedily, largest deviation first (ties by
/// position, so the order does not depend on threads), each first put on the input's box when
/// within 0.002 voxel of it: a candidate closer than its exclusion radius to an already accepted
/// candidate, or to a vertex of the triangulation's cell that holds it or of that cell's
/// neighbours, is skipped. The accepted ones go in in Z-order (short walks) on a grid of `cell`
/// mm. Returns the new vertices (info = kRefinementPoint); their cells are not labelled yet.
std::vector<Delaunay::Vertex_handle> insertCandidates(const IndicatorField& field, Delaunay& dt,
                                                      std::vector<Candidate> cand, double cell,
                                                      int threads);

}  // namespace internal

struct LabelledDelaunay::Impl {
  internal::Delaunay dt;
  int labels = 0;
};

}  // namespace femesher
