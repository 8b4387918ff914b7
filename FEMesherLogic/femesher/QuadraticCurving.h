// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file QuadraticCurving.h
/// Curved 10-node tets (`element_order` = 2): the mid-edge nodes of edges on an interface or on
/// the outer boundary are moved from the straight edge midpoint onto the smooth surface the
/// linear mesh approximates, where that keeps every element around the edge valid.
///
/// Edge classes, from the faces of the linear mesh that contain the edge (interface triangles:
/// two materials a < b either side; outer faces: the material and the background 0; faces on
/// the volume's box are neither):
///  - every such face between the same two materials a, b: the node moves onto f_a = f_b
///    (OptimizeInterfaces::projectOntoInterface, the run's indicator functions);
///  - faces of exactly three materials a < b < c, pairwise (a triple line, the background
///    counted): the node moves onto the triple line (projectOntoJunction);
///  - an edge on a face on the volume's box: the node stays in that box plane. Between two
///    materials (an interface meeting the box) it moves along the interface's trace on the plane
///    (projections onto the interface alternating with the plane); lying in two box planes (a box
///    edge) or on box faces only (flat) it stays at the midpoint;
///  - anything else (interior edges, junctions of four materials, pinched interfaces): straight.
/// Every curved node is clamped into the volume's box, so it never leaves the volume.
///
/// Validity: the determinant of the quadratic map's Jacobian of every tet around the edge is
/// evaluated at its 4 corners, 6 mid-edge nodes and centroid (`kTet10CheckPoints`, with the
/// nodes already curved around it); the move is kept when each is at least
/// `minJacobianFraction` × the straight-sided tet's (6 × its volume) and the smallest is at least
/// `minScaledJacobian` × the largest (a bulge that keeps the determinant positive but makes it
/// vary much over the element is refused too). Otherwise the node moves
/// half as far, then a quarter, an eighth, and finally stays at the midpoint. A projection that
/// fails, or lands farther from the midpoint than half the edge's length or twice
/// `OptimizeInterfaces::facetDistance` (the surface stage leaves interface edge midpoints within
/// the facet distance of their interface), leaves it straight.
/// Edges are visited in ascending order of their vertex indices (deterministic).

#include <femesher/Types.h>
#include <femesher/io/QuadraticTets.h>
#include <femesher/stages/Optimize.h>

#include <cstddef>

namespace femesher {

class RunContext;

struct QuadraticCurvingParameters {
  /// Every check point's Jacobian determinant must stay at least this fraction of the
  /// straight-sided tet's (0 < fraction < 1).
  double minJacobianFraction = 0.2;
  /// ... and its smallest over its largest determinant (the curved element's scaled Jacobian, 1
  /// for a straight tet) at least this (0 < value <= 1).
  double minScaledJacobian = 0.25;
  /// Halvings of the move tried after the full one before the node stays straight.
  int halvings = 3;
};

struct QuadraticCurvingResult {
  /// The curved mid-edge nodes (in the frame of the mesh given), by tetEdgeKey.
  MidEdgePositions nodes;
  size_t midEdgeNodes = 0;       ///< unique edges of the mesh (every mid-edge node)
  size_t surfaceNodes = 0;       ///< nodes of edges on an interface, the outer boundary or the box
  size_t curvedNodes = 0;        ///< moved the whole way onto their interface (or triple line)
  size_t partlyCurvedNodes = 0;  ///< moved part of the way (a half, quarter or eighth)
  size_t straightKept = 0;       ///< surface nodes left straight (projection failed, or validity)
  size_t onInterfaceNodes = 0;  ///< surface nodes whose midpoint is on the interface already (flat)
  size_t tripleLineNodes = 0;   ///< nodes moved (wholly or partly) along a triple line
  size_t boxPlaneNodes = 0;     ///< nodes moved (wholly or partly) along a trace on a box plane
  double meanMove = 0;          ///< mean distance (mesh units) the moved nodes moved
  double maxMove = 0;           ///< the largest
  /// The worst figures of the quadratic elements (straight ones count as 1).
  Tet10Jacobian worst;
};

/// Curves the mid-edge nodes of `mesh` (any frame in mm, positively oriented tets, labels
/// matching `interfaces`' materials, 0 = background) onto `interfaces` (see the file comment).
/// Without interfaces (`interfaces.projectOntoInterface` empty) nothing moves. Checks cancel.
QuadraticCurvingResult curveMidEdgeNodes(const TetMesh& mesh, const OptimizeInterfaces& interfaces,
                                         const QuadraticCurvingParameters& params, RunContext& ctx);

/// Report figures: quadratic_mid_edge_nodes, quadratic_surface_nodes, quadratic_curved_nodes,
/// quadratic_partly_curved_nodes, quadratic_straight_kept, quadratic_on_interface_nodes (the
/// four add up to the surface nodes), quadratic_triple_line_nodes,
/// quadratic_box_plane_nodes, quadratic_mean_move_mm, quadratic_max_move_mm,
/// quadratic_min_jacobian_fraction (smallest det J over the straight tet's), and
/// quadratic_worst_scaled_jacobian (smallest over largest det J of an element, 1 = straight).
ReportCounts reportCounts(const QuadraticCurvingResult& result);

}  // namespace femesher
