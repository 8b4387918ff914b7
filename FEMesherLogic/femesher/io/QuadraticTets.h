// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file QuadraticTets.h
/// Second-order (10-node) tetrahedra for the solver exports (`element_order` = 2): one mid-edge
/// node per unique edge of the linear mesh, shared by every tet around that edge (so the
/// quadratic mesh is conformal across materials exactly as the linear one is). Mid-edge nodes sit
/// at the straight edge midpoint, so every 10-node tet has the same (positive) Jacobian as its
/// linear tet everywhere.
///
/// Node order of `QuadraticTetMesh::tets`: the four corners, then the mid-edge nodes of the edges
/// (0,1), (1,2), (2,0), (0,3), (1,3), (2,3) (`kTet10Edges`). This is the order of Abaqus/CalculiX
/// C3D10, of VTK_QUADRATIC_TETRA and of FEBio's tet10; Gmsh's 10-node tetrahedron (type 11) has
/// the last two swapped (`kGmshTet10Order`).

#include <femesher/Types.h>

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace femesher {

/// The corner pairs of the six mid-edge nodes, in C3D10 / VTK / FEBio order.
inline constexpr std::array<std::array<int, 2>, 6> kTet10Edges{
    {{{0, 1}}, {{1, 2}}, {{2, 0}}, {{0, 3}}, {{1, 3}}, {{2, 3}}}};

/// Gmsh order of a tet10: node k of Gmsh's element is node kGmshTet10Order[k] of ours (Gmsh
/// puts the midpoint of edge (2,3) before that of (1,3)).
inline constexpr std::array<int, 10> kGmshTet10Order{{0, 1, 2, 3, 4, 5, 6, 7, 9, 8}};

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

/// The 10-node version of `m` (straight edges, midpoints). Mid-edge nodes are numbered in the
/// order their edge is first met, tet by tet, edge by edge in `kTet10Edges` order.
QuadraticTetMesh quadraticTets(const TetMesh& m);

}  // namespace femesher
