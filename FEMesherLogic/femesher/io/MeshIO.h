// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file MeshIO.h
/// Writing (and reading back) labelled tet meshes. The format follows the extension:
///  - .vtu  VTK XML unstructured grid; cell array `labels` (int32 user ids), numeric field data
///          only (meshio reads it): `MaterialIds`, `MaterialNames` (UTF-8 text as UInt8),
///          `MaterialColors`, `FEMesherVersion`, `Provenance` (VtkConversion.h). No `SPACE` tag:
///          Slicer takes a model file without one as LPS.
///  - .inp  Abaqus/CalculiX: C3D4 (C3D10 with element_order 2), an ELSET + *SOLID SECTION + named *MATERIAL (*ELASTIC,
///          *DENSITY) per material, NSET `BOUNDARY` (outer boundary nodes), an element-based
///          *SURFACE per material interface and per material's outer boundary.
///  - .msh  Gmsh MSH 4.1 ASCII: a named physical volume per material, a named physical surface
///          per interface.
///  - .mesh Medit (INRIA) ASCII: tets with material refs, interface triangles with refs.
///  - .feb  FEBio input file, format 4.0: Module solid, a static Control step, a named material
///          per label (neo-Hookean from E/nu, density), Nodes, an Elements domain (tet4) per
///          material with ids unique over the file, NodeSets per material, interface and outer
///          boundary, a Surface per interface (<a>__<b>, outward from a) and per material's outer
///          boundary (<a>__boundary), and a SolidDomain per material. Names: `febioNames`.
///  - .stl  ASCII STL: one `solid` per interface (outward from the lower label).
///  - .vtk  legacy VTK (binary, Slicer's "SPACE=LPS" header, which Slicer reads): cell array
///          `labels`, no field data.
/// .inp and .feb also write `ExportOptions::contacts` (split interfaces as contact pairs) and
/// `ExportOptions::nodeSets` (the box-face node sets); see ExportOptions.
/// All writers are atomic (temporary file + rename). Coordinates are written in LPS mm.
/// With `ExportOptions::elementOrder` = 2 the .inp, .msh, .vtu, .vtk and .feb writers write
/// 10-node tets (QuadraticTets.h: one node per unique edge, at its midpoint or where
/// `ExportOptions::midEdgeNodes` puts it on the smooth interfaces, node order of
/// each format: C3D10, Gmsh type 11, VTK_QUADRATIC_TETRA, FEBio tet10), the .msh its interface
/// triangles as 6-node triangles (type 9), the .feb its surfaces as tri6 and its NodeSets with
/// the mid-edge nodes; the .inp NSET BOUNDARY holds the boundary's mid-edge nodes too (its
/// element-face surfaces are the same for C3D10). .mesh and .stl cannot hold them
/// (`checkExportable`).

#include <femesher/Parameters.h>
#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/io/ContactSplit.h>
#include <femesher/io/QuadraticTets.h>

#include <map>
#include <string>
#include <vector>

namespace femesher {

struct ExportOptions {
  ElasticProperties defaultMaterial;                       ///< for every material ...
  std::map<int32_t, ElasticProperties> materialProperties;  ///< ... unless overridden here
  /// True when the user chose `defaultMaterial` (default.E, .nu or .density differ from the
  /// built-in values); false means it is the silent built-in default (see
  /// `defaultPropertiesWarning`).
  bool defaultMaterialGiven = false;
  /// Extra provenance written where the format allows (VTU field data, comments).
  std::string provenance;
  /// 1: 4-node tets; 2: 10-node tets (parameter `element_order`; see the file comment).
  int elementOrder = 1;
  /// With element order 2: the curved mid-edge nodes of the mesh being written
  /// (PipelineResult::midEdgeNodes, QuadraticCurving.h); every writer puts those nodes there and
  /// the others at their edge's midpoint. Null: every mid-edge node straight.
  std::shared_ptr<const MidEdgePositions> midEdgeNodes;
  /// Interfaces split for contact (`splitContactInterfaces`, PipelineResult::contacts) of the
  /// mesh being written. .inp: element-face *SURFACEs CONTACT_<a>_<b>_S (faces of a's elements,
  /// the dependent side) and CONTACT_<a>_<b>_M (b's, the independent side), a *SURFACE
  /// INTERACTION with a linear pressure-overclosure penalty and a *CONTACT PAIR, TYPE=SURFACE TO
  /// SURFACE. .feb: Surfaces contact__<a>__<b>__<a> and ...__<b> (faces outward from their own
  /// tets), a SurfacePair contact__<a>__<b> (primary a, secondary b) and a sliding-elastic
  /// <Contact>. Other formats carry the split as the duplicated nodes only. The split faces also
  /// belong to each side's outer boundary (OUTER_<a>, <a>__boundary, NSET BOUNDARY).
  std::vector<ContactSurfacePair> contacts;
  /// Extra named node sets (PipelineResult::boxNodeSets): .inp *NSET, .feb <NodeSet>; with
  /// element order 2 they also hold the mid-edge node of every edge whose two ends they hold.
  std::vector<NamedNodeSet> nodeSets;
};

/// Export options from the meshing parameters (material properties).
ExportOptions exportOptionsFrom(const MeshingParameters& params);

/// The warning a solver deck deserves before it is written to `path` (.inp or .feb; "" for other
/// formats): the materials of `mesh` the user gave no properties for (no material.<label>.E,
/// .nu or .density, and no default.*), which the deck gets with the built-in E = 1000 MPa,
/// nu = 0.3, density 1e-9 t/mm^3: one sentence naming the file, those materials and how to set
/// them. "" when every material has the user's properties.
std::string defaultPropertiesWarning(const TetMesh& mesh, const std::string& path,
                                     const ExportOptions& options);

/// Extensions `writeMesh` accepts, e.g. {".vtu", ".inp", ".msh", ".mesh", ".feb", ".stl"}.
std::vector<std::string> supportedMeshExtensions();

/// Whether `path`'s format can be written with `options` before any work is done: InvalidArgument
/// for an unknown extension, for an element order other than 1 or 2, and for element order 2 in a
/// format that has no 10-node tets (.mesh, .stl). `writeMesh` checks it too.
Status checkExportable(const std::string& path, const ExportOptions& options);

/// Write `mesh` to `path` (format from the extension). InvalidArgument for an unknown extension,
/// WriteFailed for I/O errors. Never leaves a partial file.
Status writeMesh(const TetMesh& mesh, const std::string& path, const ExportOptions& options = {});

/// A mesh file as read: its corner tets and, for 10-node tets, where their mid-edge nodes are.
struct MeshFile {
  /// The tets by their corners; `points` holds the corner nodes only (mid-edge nodes dropped,
  /// corners renumbered in file order).
  TetMesh mesh;
  int elementOrder = 1;  ///< 2 when the file holds 10-node tets
  /// Order 2: the mid-edge node of every edge of `mesh` (by tetEdgeKey), as in the file.
  MidEdgePositions midEdgeNodes;
};

/// Read a tet mesh written by FEMesher (.vtu, .vtk, .inp; .msh 4.1 ASCII and .mesh too), of
/// 4-node or 10-node tets (.vtu/.vtk VTK_QUADRATIC_TETRA, .msh type 11, .inp C3D10; Medit has
/// none). Used by `femesher quality` and `optimize`. Errors: FileNotFound, UnreadableFile (wrong
/// format/version, other element types, 4-node and 10-node tets mixed), CorruptFile (among
/// others: an edge with two different mid-edge nodes, a node both a corner and a mid-edge node).
Result<MeshFile> readMeshFile(const std::string& path);

/// readMeshFile's corner mesh (a 10-node file's mid-edge nodes dropped).
Result<TetMesh> readMesh(const std::string& path);

}  // namespace femesher
