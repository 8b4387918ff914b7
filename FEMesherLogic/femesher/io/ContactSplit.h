// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file ContactSplit.h
/// What the solver decks need beyond the tets, computed on the final linear mesh just before
/// export:
///  - Contact-ready interfaces (parameter `contact_pairs`): the interface between two chosen
///    materials A and B becomes two coincident surfaces with their own nodes, written as a contact
///    pair (Abaqus/CalculiX *CONTACT PAIR, FEBio <Contact>). Around every node of an A|B interface
///    triangle the incident tets are grouped into components connected through shared faces that
///    contain the node, where A|B faces (of any chosen pair) do not connect; the first component
///    (the one holding the node's lowest incident tet) keeps the node, every other one gets its
///    own copy at the same position. A third material C therefore stays attached to whichever
///    side it touches through a face; on a triple line where C touches both A and B the node stays
///    shared (C holds the two sides together there). Tets keep their index, label, volume and
///    orientation; only vertex indices change, so each side's element faces are the triangles it
///    had.
///  - Node sets of the cut faces of the scan box: the mesh nodes lying on each of the six faces of
///    the input volume's box (the voxel-edge planes index = -0.5 and dims - 0.5, where the
///    indicator functions end the materials cut by the scan boundary): where fixations go.

#include <femesher/Status.h>
#include <femesher/Types.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

/// One element face: tet `tet`, the face opposite its local vertex `opposite` (0..3).
struct ElementFace {
  int32_t tet = -1;
  int32_t opposite = 0;
};

/// One split interface: the faces of A's tets and of B's tets that lay on the A|B interface (one
/// per interface triangle on each side, same order), and how many node copies the split made at
/// the nodes of these triangles (a node shared with another split pair is counted in both).
struct ContactSurfacePair {
  int32_t labelA = 0;  ///< as the user named the pair first (the dependent/slave side in decks)
  int32_t labelB = 0;  ///< second label (the independent/master side)
  std::vector<ElementFace> facesA, facesB;
  size_t duplicatedNodes = 0;
};

/// Parses "2:4,6:5" (label pairs, whitespace allowed, "" = none) into pairs. InvalidArgument
/// (thrown as femesher::Error) naming the text and the expected form for anything else, a pair of
/// one label with itself, or a pair given twice (in either order).
std::vector<std::pair<int32_t, int32_t>> parseContactPairs(const std::string& text);

/// "2:4,6:5" from pairs (the inverse of parseContactPairs).
std::string contactPairsText(const std::vector<std::pair<int32_t, int32_t>>& pairs);

/// Checks `pairs` against the label map `input` before meshing: InvalidArgument naming the pair
/// and what to do when a label is not in the map (or is its background 0) or when the two labels
/// have no face-adjacent voxels (no interface to split). `MeshingRun` calls it up front.
Status checkContactPairs(const std::vector<std::pair<int32_t, int32_t>>& pairs,
                         const LabelVolume& input);

/// Splits the interfaces of `pairs` in `mesh` (see the file comment) and returns one entry per
/// pair, in the order given. Throws Error(InvalidArgument) when a label of a pair has no tets in
/// the mesh or the two labels share no interface triangle, naming the labels and what to do.
/// `mesh` must be a valid conformal mesh (extractInterfaces).
std::vector<ContactSurfacePair> splitContactInterfaces(
    TetMesh& mesh, const std::vector<std::pair<int32_t, int32_t>>& pairs);

/// A named set of node indices (ascending).
struct NamedNodeSet {
  std::string name;
  std::vector<int32_t> nodes;
};

/// The nodes of `mesh` (LPS mm) on each face of the box of `geometry` (the label map the mesh was
/// made from: dims, spacing, origin, direction): BOX_XMIN, BOX_XMAX, BOX_YMIN, ..., BOX_ZMAX,
/// where X, Y and Z are the image's own voxel axes i, j, k (X = the first axis, whose direction in
/// LPS is the first column of `geometry.direction`; for an unrotated axial scan X runs to the
/// patient's left, Y to posterior, Z to superior; an oblique image's axes are its own, not LPS).
/// MIN is the plane at voxel index -0.5, MAX at dims - 0.5 (the outer voxel edges). A node is on a
/// face within `toleranceVoxels` of the plane. Only non-empty sets are returned, in that order.
std::vector<NamedNodeSet> boxFaceNodeSets(const TetMesh& mesh, const LabelVolume& geometry,
                                          double toleranceVoxels = 1e-4);

}  // namespace femesher
