// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Types.h
/// The value types every layer exchanges: `LabelVolume` (the input) and `TetMesh` (the output).
///
/// Coordinates: physical LPS millimetres (ITK convention). A voxel index v = (i,j,k) maps to
///   x(v) = origin + D * (spacing ⊙ v)
/// with D the 3x3 direction matrix (columns = directions of the voxel axes), so the origin is the
/// centre of voxel (0,0,0). Algorithms work in the *canonical frame* c = spacing ⊙ v (no rotation,
/// no origin) and map to LPS only at the end (`LabelVolume::canonicalToPhysical`).

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

using Vec3 = std::array<double, 3>;
using Mat3 = std::array<double, 9>;  ///< row-major 3x3: m[3*r + c]

/// Named figures a stage result contributes to the run report ("tets", "surface_samples", ...),
/// in report order.
using ReportCounts = std::vector<std::pair<std::string, double>>;

/// One material (label) of a label map or a mesh.
struct Material {
  int32_t id = 0;                     ///< label value as in the user's file
  std::string name;                   ///< e.g. "cortical bone"; "label 7" when unknown
  std::array<double, 3> color{{0.5, 0.5, 0.5}};  ///< RGB in [0,1]
};

/// Default colour for a label id (a fixed, well-separated palette; deterministic).
std::array<double, 3> defaultLabelColor(int32_t id);

/// Find a material by id; nullptr when absent.
const Material* findMaterial(const std::vector<Material>& table, int32_t id);

/// A 3-D label map: one int32 material id per voxel, x fastest, then y, then z.
/// Label 0 is the background (not meshed) unless the map has no 0 at all.
struct LabelVolume {
  std::array<int, 3> dims{{0, 0, 0}};
  Vec3 spacing{{1, 1, 1}};  ///< mm, all > 0
  Vec3 origin{{0, 0, 0}};   ///< LPS mm, centre of voxel (0,0,0)
  Mat3 direction{{1, 0, 0, 0, 1, 0, 0, 0, 1}};  ///< row-major; columns = axis directions in LPS
  std::vector<int32_t> labels;                  ///< dims[0]*dims[1]*dims[2] values
  /// Materials present in the map (non-background), sorted by id. Names and colours come from a
  /// .seg.nrrd header when available, otherwise defaults ("label N", `defaultLabelColor`).
  std::vector<Material> materials;
  std::string sourcePath;  ///< where it was read from (for messages); may be empty

  size_t voxelCount() const { return size_t(dims[0]) * size_t(dims[1]) * size_t(dims[2]); }
  size_t index(int i, int j, int k) const {
    return size_t(i) + size_t(dims[0]) * (size_t(j) + size_t(dims[1]) * size_t(k));
  }
  int32_t at(int i, int j, int k) const { return labels[index(i, j, k)]; }
  bool inside(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < dims[0] && j < dims[1] && k < dims[2];
  }
  /// Canonical frame (spacing ⊙ index, mm) -> physical LPS.
  Vec3 canonicalToPhysical(const Vec3& c) const;
  /// Physical LPS -> canonical frame (inverse of the above; direction must be invertible).
  Vec3 physicalToCanonical(const Vec3& p) const;
  /// Continuous voxel index -> physical LPS.
  Vec3 indexToPhysical(const Vec3& ijk) const;
  /// Physical LPS -> continuous voxel index.
  Vec3 physicalToIndex(const Vec3& p) const;
  /// Determinant of the direction matrix (+1 right-handed, -1 left-handed).
  double directionDeterminant() const;
  /// True when the label map contains no voxel of label 0.
  bool hasNoBackground() const;
};

/// A labelled tetrahedral mesh in physical LPS millimetres.
/// Tets are positively oriented: (p1-p0)·((p2-p0)×(p3-p0)) > 0.
struct TetMesh {
  std::vector<Vec3> points;
  std::vector<std::array<int32_t, 4>> tets;
  std::vector<int32_t> tetLabels;  ///< one user label id per tet
  std::vector<Material> materials; ///< materials present in the mesh, sorted by id

  size_t tetCount() const { return tets.size(); }
  /// Signed volume of tet t (positive when correctly oriented).
  double tetVolume(size_t t) const;
};

/// Label "pair partner" used for faces on the outer boundary of the mesh (background/outside).
constexpr int32_t kExteriorLabel = -1;

/// A triangle of the multi-material surface: a face between two tets of different materials, or
/// a boundary face (labelB == kExteriorLabel). Vertex order is outward from `labelA`'s tet.
struct InterfaceTriangle {
  std::array<int32_t, 3> v;
  int32_t labelA = 0;
  int32_t labelB = kExteriorLabel;
  int32_t tetA = -1;  ///< the tet of labelA owning this face
  int32_t tetB = -1;  ///< the tet on the other side, -1 on the boundary
};

/// Every face of the mesh whose two sides differ in material (or that lies on the boundary).
/// Each shared face appears once, with labelA < labelB for interior interfaces.
/// Throws Error(MeshingFailed) if a face is shared by more than two tets.
std::vector<InterfaceTriangle> extractInterfaces(const TetMesh& mesh);

}  // namespace femesher
