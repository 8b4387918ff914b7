// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file VtkConversion.h
/// The logic library's VTK adapter (deliberately VTK-facing): FEMesher's value types to and from
/// VTK data objects, written once for the .vtu/.vtk formats, the GUI's 3-D view and the 3D Slicer
/// module. VTK classes are only forward-declared, so including this header needs no VTK include
/// path; calling it needs VTK (CommonDataModel) linked.
///
/// Label maps come in through `labelVolumeFromVtkImage`, checked as LabelValidation.h says.
///
/// Frames: FEMesher is in LPS millimetres (the ITK convention, see Types.h). A VTK object may be
/// in LPS (files, the GUI view) or in RAS (3D Slicer's scene); LPS <-> RAS negates x and y, a
/// rotation by 180 degrees about S, so tets keep their orientation. Nothing else is changed:
/// coordinates of an oblique or left-handed mesh pass through bit for bit.

#include <femesher/Status.h>
#include <femesher/Types.h>

#include <string>

class vtkImageData;
class vtkMatrix4x4;
class vtkUnstructuredGrid;

namespace femesher {

/// Frame of the coordinates of a VTK object.
enum class VtkFrame { LPS, RAS };

/// How `meshToVtkGrid` fills the grid.
struct VtkGridOptions {
  VtkFrame frame = VtkFrame::LPS;  ///< frame of the grid's points
  /// Add FEMesher's field data (what the .vtu writer stores): `SPACE` (string, "LPS" or "RAS"),
  /// per material present in the mesh, ascending: `MaterialIds` (int), `MaterialNames` (string,
  /// "label N" when unnamed), `MaterialColors` (double, 3 components, RGB in [0,1]); then
  /// `FEMesherVersion` (string) and `Provenance` (string, only when `provenance` is not empty).
  bool fieldData = false;
  std::string provenance;  ///< written only with `fieldData`
};

/// TetMesh -> vtkUnstructuredGrid. `grid` is reset, then gets double-precision points (mesh
/// order), one VTK_TETRA cell per tet (mesh order, vertex order kept) and the int cell array
/// `labels` (the tets' user label ids) as active cell scalars, plus field data per `options`.
/// Preconditions: `grid` is not null; mesh.tetLabels has one entry per tet and every tet's vertex
/// indices are valid (what writeMesh checks before writing).
void meshToVtkGrid(const TetMesh& mesh, vtkUnstructuredGrid* grid,
                   const VtkGridOptions& options = {});

/// vtkUnstructuredGrid -> TetMesh (the .vtu/.vtk readers): points converted from `frame` to LPS,
/// every cell must be a VTK_TETRA, material ids from the cell array `labels` (any numeric type,
/// integer values). Materials are named and coloured from the `MaterialIds`, `MaterialNames` and
/// `MaterialColors` field data when present, else "label N" and defaultLabelColor(N).
/// Errors, as "Cannot read mesh '<source>': ...": CorruptFile (no cells, a non-integer label,
/// a vertex index out of range, a non-finite coordinate), UnreadableFile (no `labels` array with
/// one value per cell, a cell that is not a linear tetrahedron).
Result<TetMesh> vtkGridToMesh(vtkUnstructuredGrid* grid, const std::string& source,
                              VtkFrame frame = VtkFrame::LPS);

/// A label map held as a VTK image plus the matrix mapping its voxel indices (i, j, k, 1) to
/// `frame` mm, the way 3D Slicer keeps label map volumes (the image's own origin, spacing and
/// direction are not used). The image has one scalar component of any integer or floating-point
/// type; its voxels are read x fastest over its extent. The lengths of the matrix's first three
/// columns are the spacing, the normalized columns the direction (converted to LPS), and the
/// origin is the centre of the first voxel of the extent. Materials: one per label present,
/// "label N" coloured defaultLabelColor(N); `sourcePath` = `source`.
/// Errors, each naming `source`: InvalidArgument (no image, scalars or matrix; several components
/// per voxel; an unsupported scalar type; fewer or more values than voxels), then the errors of
/// validateLabelGeometry, labelsFromVoxels and validateLabelVolume (LabelValidation.h).
Result<LabelVolume> labelVolumeFromVtkImage(vtkImageData* image, const vtkMatrix4x4* ijkToWorld,
                                            VtkFrame frame, const std::string& source);

}  // namespace femesher
