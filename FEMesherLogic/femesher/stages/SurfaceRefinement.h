// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file SurfaceRefinement.h
/// Stage 8's refinements of a labelled Delaunay triangulation (LabelledDelaunay.h): points are
/// inserted on the interfaces where the restricted Delaunay surface of the particles strays from
/// the labels, and the tets around them are relabelled. BoundaryMesh.h runs them in this order:
/// facet distance, facet shape (only with facet_angle > 0), voxel centres, junction edges.
///
/// Every inserted point is on an interface f_a = f_b of the indicator functions (or, for the
/// junction refinement, on a triple line) and is put exactly on the input's box when within 0.002
/// voxel of it. A candidate closer than its exclusion radius to a vertex already there, or to a
/// candidate taken before it, is skipped, so the sampling stays well spaced. Each refinement runs
/// in rounds (at most 10) until nothing more goes in (the voxel-centre pass stops as soon as
/// fewer than one in 50 of its misplaced centres can be fixed). Multi-threaded; the result does not
/// depend on the thread count. Canonical frame (mm). Cancel is checked between rounds (throws the
/// Canceled error of RunContext::checkCancel).
///
/// Precondition for all four: the triangulation is labelled (LabelledDelaunay::label).

#include <femesher/Types.h>

#include <cstddef>
#include <functional>

namespace femesher {

class IndicatorField;
class LabelledDelaunay;
class RunContext;
struct Junctions;

/// Facet distance (Boissonnat & Oudot's criterion, CGAL's facet_distance): for every interface
/// triangle (a, b), the interface f_a = f_b is searched along the triangle's normal through its
/// centroid and its three edge midpoints; where it is farther than `facetDistance` (mm, > 0) the
/// farthest crossing is inserted (on the (a, b) interface, not in a third material). Triangles
/// whose shortest edge is below twice the bound are left alone; a point never comes closer than
/// half the triangle's shortest edge to another vertex. Later rounds look only at the triangles
/// around the points the previous round inserted. Returns the number of points inserted.
size_t refineFacetDistance(const IndicatorField& field, LabelledDelaunay& delaunay,
                           double facetDistance, RunContext& ctx);

/// The facet-shape criterion of refineFacetShape.
struct FacetShapeCriteria {
  double minAngleDegrees = 10;  ///< a triangle with a smaller angle is refined ...
  double sizeFactor = 1.5;      ///< ... when its longest edge exceeds this × the sizing field
};

/// Facet shape (CGAL's facet_angle, gated by size): an interface triangle (a, b) with an angle
/// below criteria.minAngleDegrees whose longest edge is longer than criteria.sizeFactor × the
/// target edge length `sizeAt` (canonical mm) at its centroid gets its surface Delaunay ball's
/// centre inserted: where the dual Voronoi edge (from circumcentre to circumcentre, or from the
/// finite cell's circumcentre outwards along the normal) crosses f_a = f_b, inside the grid and
/// not in a third material. The ball is empty, so the point is as far from every vertex as from
/// the triangle's. These needles are what a sampling on the surface only leaves on thin, straight
/// parts (a rod two voxels across: the convex hull's triangles run along it), and no later stage
/// can mend them. Returns the number of points inserted.
size_t refineFacetShape(const IndicatorField& field, LabelledDelaunay& delaunay,
                        const std::function<double(const Vec3&)>& sizeAt,
                        const FacetShapeCriteria& criteria, RunContext& ctx);

/// Voxel centres: every voxel centre next to another label (6-neighbourhood) must fall in a tet
/// of its own label (the label map's own test of the mesh, and what Dice counts). A centre that
/// does not is projected onto the interface between its label and the label it fell in (Newton
/// on f_a - f_b), and that point is inserted when it is within two voxels of the centre and a
/// quarter voxel from other vertices. Returns the number of points inserted.
size_t refineVoxelCentres(const IndicatorField& field, LabelledDelaunay& delaunay, RunContext& ctx);

struct JunctionRefinement {
  size_t inserted = 0;  ///< points inserted
  size_t stillOff = 0;  ///< junction particles on no edge of three materials afterwards
};

/// Junction edges: a junction particle (triple line or quadruple point) must be a vertex of an
/// edge around which three or more materials meet, i.e. the line must appear as mesh edges. Where
/// a particle is on no such edge:
///  - a material of its junction has no tet around it (the usual case on real data: near the line
///    that material is a wedge thinner than the sampling, e.g. the background cusp where two
///    cartilages touch). The wedge is found on small spheres around the particle (from one voxel
///    in the first round, halved in each later round, and halved again down to a sixteenth of a
///    voxel until the material covers a tenth of the sphere); the interfaces bounding it there get
///    a point each, and the line gets the points about that far from the particle on either side.
///  - all its materials are there but on no common edge: the line points about the round's radius
///    from it on either side are inserted (else the located line point of Junctions::candidates
///    nearest to the midpoint between the particle and its nearest neighbour on the same line, if
///    at least a fifth of their distance from both).
/// Precondition: junctions.particles[j] is the point given at index j to LabelledDelaunay::insert
/// (junction particles first); particles with no vertex are skipped.
JunctionRefinement refineJunctionEdges(const IndicatorField& field, LabelledDelaunay& delaunay,
                                       const Junctions& junctions, RunContext& ctx);

}  // namespace femesher
