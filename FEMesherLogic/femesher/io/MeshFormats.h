// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file MeshFormats.h
/// Private to the io/*Format.cxx files and io/MeshIO.cxx (not part of the public API): one
/// writer (and, where FEMesher reads the format back, one reader) per mesh format, and the small
/// helpers the formats share. `writeMesh`/`readMesh` (MeshIO.h) dispatch on the extension and
/// check the mesh first, so every writer may assume a mesh with tets, one label per tet and valid
/// vertex indices. Writers return WriteFailed on I/O errors; readers return FileNotFound,
/// UnreadableFile or CorruptFile with a "Cannot read mesh '<path>': ..." message.

#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/io/AtomicFile.h>
#include <femesher/io/MeshIO.h>
#include <femesher/io/QuadraticTets.h>

#include <cstdio>
#include <istream>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace femesher::meshio {

// --- Writers, one per format (io/<Format>Format.cxx) ---------------------------------------------

Status writeVtu(const TetMesh& m, const std::string& path, const ExportOptions& o);
Status writeLegacyVtk(const TetMesh& m, const std::string& path, const ExportOptions& o);
Status writeInp(const TetMesh& m, const std::string& path, const ExportOptions& o);
Status writeMsh(const TetMesh& m, const std::string& path, const ExportOptions& o);
Status writeMedit(const TetMesh& m, const std::string& path, const ExportOptions& o);
Status writeFeb(const TetMesh& m, const std::string& path, const ExportOptions& o);
Status writeStl(const TetMesh& m, const std::string& path, const ExportOptions& o);

// --- Readers
// ---------------------------------------------------------------------------------------

/// With `midNodes`, the .vtu, .vtk, .msh and .inp readers also take 10-node tets: the corners are
/// the tet, the six mid-edge nodes (kTet10Edges order, whatever the file's) one entry of
/// `midNodes` per tet (-1s for a 4-node tet). Without it a 10-node tet is an error.
Result<TetMesh> readVtu(const std::string& path, std::vector<std::array<int32_t, 6>>* midNodes = nullptr);
Result<TetMesh> readLegacyVtk(const std::string& path,
                              std::vector<std::array<int32_t, 6>>* midNodes = nullptr);
Result<TetMesh> readMedit(const std::string& path);
Result<TetMesh> readMsh(const std::string& path, std::vector<std::array<int32_t, 6>>* midNodes = nullptr);
/// Abaqus/CalculiX input as FEMesher writes it: *NODE, *ELEMENT TYPE=C3D4 or C3D10 with
/// ELSET=M<label>_<name> (N<label> for a negative label), names from the header comments; other
/// keywords are skipped.
Result<TetMesh> readInp(const std::string& path, std::vector<std::array<int32_t, 6>>* midNodes = nullptr);

// --- Shared helpers (io/MeshFormats.cxx)
// -----------------------------------------------------------

/// (labelA, labelB) of an interface patch; labelB = kExteriorLabel on the outer boundary.
using PatchKey = std::pair<int32_t, int32_t>;

/// Elastic properties of `label`: its override in `o`, else the default material.
const ElasticProperties& propsFor(const ExportOptions& o, int32_t label);

/// The material's name, or "label N" when the mesh has none for `label`.
std::string materialName(const TetMesh& m, int32_t label);

/// Printable one-line text: control characters (newlines, tabs) become spaces; `drop` removed.
std::string oneLine(const std::string& s, const char* drop = "");

/// Labels of the tets, ascending, each once.
std::vector<int32_t> meshLabels(const TetMesh& m);

/// Tet indices per label, in mesh order.
std::map<int32_t, std::vector<size_t>> tetsByLabel(const TetMesh& m);

/// Interface triangles grouped into patches (interfaces between two materials and per-material
/// outer boundaries), patches sorted by (labelA, labelB) with the boundary patches of a label
/// (labelB = -1) first.
std::map<PatchKey, std::vector<size_t>> patchesOf(const std::vector<InterfaceTriangle>& tris);

/// "interface_1_2" or "boundary_1" (Gmsh physical names, Medit comments, FEBio surfaces, STL
/// solid names).
std::string patchName(const PatchKey& k);

/// Unique, safe Abaqus names of the element sets, one per label: M<label>_<NAME>, <= 46 chars
/// (so that "*SOLID SECTION, ELSET=<elset>, MATERIAL=MAT_<elset>" fits CalculiX's 132-character
/// lines and every name its 80-character limit). FEBio domains use the same names.
std::map<int32_t, std::string> abaqusElsetNames(const TetMesh& m);

/// What the solver decks (Abaqus, FEBio) are written from: tets per label, the interface and
/// boundary triangles grouped into patches, and the element-set names.
struct SolverDeckTables {
  explicit SolverDeckTables(const TetMesh& m)
      : byLabel(tetsByLabel(m)), tris(extractInterfaces(m)), patches(patchesOf(tris)),
        elset(abaqusElsetNames(m)) {}
  std::map<int32_t, std::vector<size_t>> byLabel;
  std::vector<InterfaceTriangle> tris;
  std::map<PatchKey, std::vector<size_t>> patches;
  std::map<int32_t, std::string> elset;
};

/// Unique, XML-safe identifiers of the materials for FEBio, one per label: the material's name
/// with every run of characters other than ASCII letters and digits turned into one underscore
/// ("femoral cartilage" -> "femoral_cartilage"), starting with a letter ("m_" before a leading
/// digit; "label_<label>" for a name with no letter or digit), at most 48 characters, never
/// "boundary" or "nodes" and never with "__" inside (FEBio surface and node-set names join
/// identifiers with "__"); on a clash "_<label>" is appended.
std::map<int32_t, std::string> febioNames(const TetMesh& m);

/// One-line material names that are unique within the mesh (Gmsh physical names): the name, or
/// "<name> (label N)" when another material has the same name; `drop` characters removed.
std::map<int32_t, std::string> uniqueMaterialNames(const TetMesh& m, const char* drop = "");

/// Label as it may appear inside an Abaqus identifier: 7 -> "7", -7 -> "N7".
std::string labelToken(int32_t l);

/// The nodes of `set` and, with `q` (element order 2), the mid-edge node of every tet edge whose
/// two ends are in the set (a set of nodes on a plane then holds its mid-edge nodes too);
/// ascending, 0-based.
std::vector<int32_t> exportedNodeSet(const TetMesh& m, const NamedNodeSet& set,
                                     const QuadraticTetMesh* q);

/// The corners of element face `f`, ordered so that the right-hand normal points out of its tet.
std::array<int32_t, 3> outwardFace(const TetMesh& m, const ElementFace& f);

/// WriteFailed "Cannot write '<path>': the disk may be full or the folder not writable."
Status ioError(const std::string& path);

/// Writes a text file atomically: `body(FILE*)` writes the content; I/O errors -> ioError.
template <class F>
Status writeText(const std::string& path, F&& body) {
  return writeAtomically(path, [&](const std::string& tmp) {
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    if (!f) return ioError(path);
    body(f);
    const bool ok = std::ferror(f) == 0;
    if (std::fclose(f) != 0 || !ok) return ioError(path);
    return Status::ok();
  });
}

/// Error of a reader: `code`, "Cannot read mesh '<path>': <what>".
Result<TetMesh> fail(ErrorCode code, const std::string& path, const std::string& what);

/// Checks indices, sizes and coordinates of a mesh just read (CorruptFile otherwise) and fills its
/// material table: one material per label, named from `names` and coloured from `colors` when
/// they have the label, else "label N" and defaultLabelColor(N).
Result<TetMesh> finishRead(TetMesh m, const std::string& path,
                           const std::map<int32_t, std::string>& names,
                           const std::map<int32_t, std::array<double, 3>>& colors = {});

/// Whitespace-separated tokens of a text mesh; a missing or malformed token throws
/// Error(CorruptFile) naming the file and `what` was expected.
class Tokens {
 public:
  Tokens(std::istream& in, std::string path) : in_(in), path_(std::move(path)) {}
  bool next(std::string& w) { return bool(in_ >> w); }
  template <class T>
  T get(const char* what) {
    T v{};
    if (!(in_ >> v))
      throw Error(
          ErrorCode::CorruptFile,
          "Cannot read mesh '" + path_ + "': truncated or malformed " + std::string(what) + ".");
    return v;
  }
  void skipLine() {
    std::string s;
    std::getline(in_, s);
  }
  std::string line() {
    std::string s;
    std::getline(in_, s);
    return s;
  }

 private:
  std::istream& in_;
  std::string path_;
};

}  // namespace femesher::meshio
