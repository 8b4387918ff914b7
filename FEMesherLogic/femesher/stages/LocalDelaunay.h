// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LocalDelaunay.h
/// The paper's side contribution, done with a true 1-ring: a surface mesher that triangulates each
/// particle's neighbourhood in its tangent plane (`--set surface_mesher=ldt`), and closes what the
/// local triangulations leave open.
///
/// For every interface patch (a,b) and every particle p of it (junction particles belong to every
/// patch whose two labels they hold):
///  0. Normals. n_p is the unit gradient of f_b - f_a at p, averaged (`normalSmoothing` passes)
///  with
///     the normals of p's Delaunay neighbours on the same patch that do not point the other way:
///     the raw gradient is noisy at the voxel scale (staircase, thin parts), and neighbours on one
///     sheet with normals 90 degrees apart were the main source of missing candidates.
///  1. Triple lines. The junction particles of each label triple are linked into polylines: the
///     shortest Delaunay 2-ring pairs first, then line ends to line ends within the 3-ring; a
///     particle takes at most two links per line, pointing apart (`lineTurn`), and a triple
///     particle links roughly along the line tangent grad(f_a - f_b) x grad(f_a - f_c)
///     (`lineAlongTangent`). These links are the rims of the three patches that meet at the line.
///  2. Stars. p's candidates are its neighbours in the 3-D Delaunay triangulation of all particles
///     (natural neighbours; the 1-ring, or the 2-ring with `candidateRings` = 2) on the same patch,
///     within `candidateRadius` times p's local spacing, whose normals agree with p's
///     (n_p . n_q >= `normalAgreement`: the two sheets of a thin layer stay apart). They are
///     projected on p's tangent plane and triangulated (constrained 2-D Delaunay, CGAL) with the
///     rim links as constraints; the triangles around p form its star. A star triangle on the far
///     side of a rim link (towards the line's third material) or spanning three particles of one
///     line is dropped.
///  3. Selection. Star triangles are taken most-voted first (a triangle's votes are the stars of
///     its corners that contain it), restricted-Delaunay facets first among equal votes, then the
///     better shaped. A triangle is accepted only if its patch stays an oriented 2-manifold: at
///     most two triangles per edge (one on a rim link), in opposite directions, no corner whose fan
///     of triangles overlaps it in that corner's tangent plane, no vertex triple used twice.
///     Triangles with fewer than `minVotes` votes are then taken when they close at least two
///     open edges of their patch (more than they open).
///  4. Hole loops. Per patch, the edges used once, the rim links the patch does not use and the
///     edges open for exactly the patch's two materials (a piece of triple line the links missed)
///     are traced into loops in the tangent planes. Each loop is triangulated without new
///     vertices: by a constrained 2-D Delaunay triangulation of its polygon in the plane of its
///     Newell normal when it projects to a simple polygon there, else by CGAL's minimum-weight
///     triangulation of the 3-D polygon (`triangulate_hole_polyline`: largest dihedral angle,
///     then area, with each loop edge's neighbouring triangle so the fill does not fold onto it).
///     A fill is kept when it passes the edge checks of step 3.
///  5. Restricted-Delaunay closure (last resort, `restrictedClosure`). Whatever is still open --
///  per
///     material, an edge used an odd number of times -- is closed with the restricted Delaunay
///     surface built from the same particles: the triangles in which the two surfaces differ are
///     grouped into components (at each edge, a local triangle and a restricted one on the same
///     side of the same patch are paired; everything else at the edge is grouped together), and
///     every component holding an open edge is swapped (its local triangles out, its restricted
///     ones in). A swap closes the open edges it holds and opens none, so the result is
///     watertight. The same swap removes self-intersections: kept triangles that are not
///     restricted-Delaunay facets are tested (exactly, CGAL predicates) against all others, and the
///     component of an intersecting one is swapped, until none is left.
/// Every triangle's provenance is counted in the result (and the run report). Deterministic and
/// independent of the thread count: the stars are computed in parallel but merged and sorted, and
/// every later choice is made on sorted data.

#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/ParticleSystem.h>

#include <cstdint>
#include <utility>
#include <vector>

namespace femesher {

class RunContext;
struct BoundarySurface;  // BoundaryMesh.h

struct LocalDelaunayParameters {
  /// A candidate q of p's star must have n_p . n_q above this (unit normals of the same patch).
  double normalAgreement = 0.3;
  /// Passes of averaging each particle's normal with its Delaunay neighbours' on the same patch.
  int normalSmoothing = 1;
  /// Candidates: the Delaunay 1-ring (1) or 2-ring (2) on the same patch...
  int candidateRings = 1;
  /// ...within this many times the distance to the sixth-nearest agreeing Delaunay neighbour.
  double candidateRadius = 3.0;
  /// Two links of a particle on one triple line must satisfy cos(angle) < this (they point apart).
  double lineTurn = 0.3;
  /// A link must satisfy |cos(angle to the line tangent)| >= this at a triple particle.
  double lineAlongTangent = 0.3;
  /// Star triangles with at least this many votes (1-3) are accepted first.
  int minVotes = 2;
  /// Trace and fill hole loops by a constrained triangulation of each loop (step 4).
  bool fillLoops = true;
  /// Close what is still open, and remove self-intersections, with the restricted Delaunay
  /// surface (step 5). Off: the result may be open (see `openEdgesAfter`).
  bool restrictedClosure = true;
};

struct LocalDelaunayResult {
  std::vector<std::array<int32_t, 3>> triangles;  ///< indices into the particle list
  /// Compact label pair (first < second) of each triangle; the triangle's normal points from
  /// `first` into `second`.
  std::vector<std::pair<uint16_t, uint16_t>> trianglePairs;

  // Provenance of the final triangles (they add up to triangles.size()).
  size_t fromStars = 0;       ///< star triangles with >= minVotes votes
  size_t fromSingleVote = 0;  ///< fewer votes, taken because they close open edges
  size_t fromLoopFill = 0;    ///< constrained triangulation of hole loops (no new vertices)
  size_t fromRestricted = 0;  ///< restricted-Delaunay triangles swapped in (step 5)

  size_t lineLinks = 0;               ///< triple-line links (rim edges)
  size_t lineEnds = 0;                ///< triple-line particles with fewer links than a line needs
  size_t starTriangles = 0;           ///< distinct (triangle, patch) candidates from the stars
  size_t nonManifoldRemoved = 0;      ///< candidates with >= minVotes votes rejected by the checks
  size_t openEdgesBefore = 0;         ///< open edges (summed over materials) after step 3
  size_t holeLoops = 0;               ///< loops traced in step 4
  size_t holesFilled = 0;             ///< loops closed in step 4
  size_t openEdgesAfterFill = 0;      ///< open edges after step 4
  size_t restrictedComponents = 0;    ///< components swapped in step 5
  size_t replacedTriangles = 0;       ///< local triangles removed by those swaps
  size_t selfIntersections = 0;       ///< intersecting pairs found before step 5's swaps
  size_t selfIntersectionsAfter = 0;  ///< intersecting pairs in the result (0 = valid PLC)
  size_t unmappedRestricted = 0;      ///< restricted triangles with a vertex that is not a particle
  size_t openEdgesAfter = 0;          ///< what is left: 0 = watertight
};

/// `restricted` must be the buildBoundaryMesh result for exactly `particles` (same order): its
/// Delaunay triangulation gives the natural neighbours, its triangles the step-5 closure (an
/// empty result when it has no triangulation).
LocalDelaunayResult buildLocalDelaunaySurface(const IndicatorField& field,
                                              const std::vector<Particle>& particles,
                                              const Junctions& junctions,
                                              const BoundarySurface& restricted,
                                              const LocalDelaunayParameters& params,
                                              RunContext& ctx);

/// Open edges of a multi-material triangle set: for every material, edges used an odd number of
/// times by the triangles bounding it (label 0 = outside is not counted).
size_t countOpenEdges(const std::vector<std::array<int32_t, 3>>& triangles,
                      const std::vector<std::pair<uint16_t, uint16_t>>& pairs);

/// Pairs of triangles that intersect other than in a shared vertex or edge (exact predicates;
/// two triangles on the same three vertices count as intersecting). `points` are the vertices.
size_t countSelfIntersections(const std::vector<Vec3>& points,
                              const std::vector<std::array<int32_t, 3>>& triangles);

}  // namespace femesher
