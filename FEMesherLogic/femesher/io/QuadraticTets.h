// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file QuadraticTets.h
/// Second-order (10-node) tetrahedra for the solver exports (`element_order` = 2): one mid-edge
/// node per unique edge of the linear mesh, shared by every tet around that edge (so the
/// quadratic mesh is conformal across materials exactly as the linear one is). Mid-edge nodes sit
/// at the straight edge midpoint, so that every 10-node tet has the same (positive) Jacobian as
/// its linear tet everywhere, unless a table of curved positions (`MidEdgePositions`, made by a
/// run: QuadraticCurving.h) moves some of them onto the smooth interfaces.
///
/// Node order of `QuadraticTetMesh::tets`: the four corners, then the mid-edge nodes of the edges
/// (0,1), (1,2), (2,0), (0,3), (1,3), (2,3) (`kTet10Edges`). This is the order of Abaqus/CalculiX
/// C3D10, of VTK_QUADRATIC_TETRA and of FEBio's tet10; Gmsh's 10-node tetrahedron (type 11) has
/// the last two swapped (`kGmshTet10Order`).

#include <femesher/Types.h>

#include <array>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

namespace femesher {

/// The corner pairs of the six mid-edge nodes, in C3D10 / VTK / FEBio order.
inline constexpr std::array<std::array<int, 2>, 6> kTet10Edges{
    {{{0, 1}}, {{1, 2}}, {{2, 0}}, {{0, 3}}, {{1, 3}}, {{2, 3}}}};

/// Gmsh order of a tet10: node k of Gmsh's element is node kGmshTet10Order[k] of ours (Gmsh
/// puts the midpoint of edge (2,3) before that of (1,3)).
inline constexpr std::array<int, 10> kGmshTet10Order{{0, 1, 2, 3, 4, 5, 6, 7, 9, 8}};

/// The key of the edge (a, b) of a linear mesh (either order) in `MidEdgePositions` and
/// `QuadraticTetMesh::edgeNodes`.
uint64_t tetEdgeKey(int32_t a, int32_t b);

/// Positions of mid-edge nodes that are not at their edge's midpoint, by `tetEdgeKey` of the
/// linear mesh's vertex indices (same frame as the mesh's points). Edges not in it are straight.
using MidEdgePositions = std::unordered_map<uint64_t, Vec3>;

struct QuadraticTetMesh {
  /// The linear mesh's vertices (same indices), then one node per unique edge.
  std::vector<Vec3> points;
  /// Per tet of the linear mesh (same order): four corners, then the six mid-edge nodes.
  std::vector<std::array<int32_t, 10>> tets;
  /// Number of corner vertices (= the linear mesh's point count).
  size_t cornerCount = 0;
  /// The mid-edge node of the edge (a, b) of the linear mesh (either order); throws
  /// Error(Internal) when (a, b) is not an edge of any tet.
  int32_t midNode(int32_t a, int32_t b) const;

  std::unordered_map<uint64_t, int32_t> edgeNodes;  ///< edge key (min, max) -> mid-edge node
};

/// The 10-node version of `m`: mid-edge nodes at the edge midpoints, or where `curved` puts them.
/// Mid-edge nodes are numbered in the order their edge is first met, tet by tet, edge by edge in
/// `kTet10Edges` order. Throws Error(Internal) when `curved` holds an edge `m` does not have (a
/// table made for another mesh).
QuadraticTetMesh quadraticTets(const TetMesh& m, const MidEdgePositions* curved = nullptr);

/// Determinant of the Jacobian of the 10-node isoparametric map (nodes in `kTet10Edges` order)
/// at natural coordinates (r, s, t) (node 0 at the origin, nodes 1, 2, 3 at the unit points).
/// A straight-sided tet has 6 × its volume everywhere.
double tet10JacobianDeterminant(const std::array<Vec3, 10>& x, double r, double s, double t);

/// The 11 points where FEMesher checks a 10-node tet (its 4 corners, 6 mid-edge nodes and the
/// centroid), in natural coordinates (r, s, t).
extern const std::array<std::array<double, 3>, 11> kTet10CheckPoints;

/// The Jacobian figures of a 10-node tet at `kTet10CheckPoints`: the smallest determinant over
/// the straight-sided tet's (6 × volume of its corners: 1 for a straight tet, <= 0 when the
/// element folds), and the smallest over the largest determinant (the "scaled Jacobian" of a
/// curved element: 1 for a straight tet). Both are -inf when the corner tet is flat or inverted.
struct Tet10Jacobian {
  double minOverStraight = 1;
  double minOverMax = 1;
};
Tet10Jacobian tet10Jacobian(const std::array<Vec3, 10>& x);

/// The worst `Tet10Jacobian` of a 10-node mesh's elements (each figure its own minimum).
Tet10Jacobian worstTet10Jacobian(const std::vector<Vec3>& points,
                                 const std::vector<std::array<int32_t, 10>>& tets);

}  // namespace femesher
