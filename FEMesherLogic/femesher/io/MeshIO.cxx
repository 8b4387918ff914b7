// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Version.h>
#include <femesher/io/AtomicFile.h>
#include <femesher/io/MeshIO.h>

#include <vtkCallbackCommand.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkCommand.h>
#include <vtkDoubleArray.h>
#include <vtkFieldData.h>
#include <vtkIdList.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkUnstructuredGridReader.h>
#include <vtkUnstructuredGridWriter.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>

namespace femesher {

namespace {

using PatchKey = std::pair<int32_t, int32_t>;  // (labelA, labelB); labelB = kExteriorLabel outside

const ElasticProperties& propsFor(const ExportOptions& o, int32_t label) {
  auto it = o.materialProperties.find(label);
  return it != o.materialProperties.end() ? it->second : o.defaultMaterial;
}

std::string materialName(const TetMesh& m, int32_t label) {
  const Material* mat = findMaterial(m.materials, label);
  return mat && !mat->name.empty() ? mat->name : "label " + std::to_string(label);
}

/// Printable one-line text: control characters (newlines, tabs) become spaces; `drop` removed.
std::string oneLine(const std::string& s, const char* drop = "") {
  std::string o;
  for (char c : s) {
    if (std::strchr(drop, c) && c != '\0') continue;
    o += static_cast<unsigned char>(c) < 0x20 ? ' ' : c;
  }
  return o;
}

/// Label as it may appear inside an Abaqus identifier: 7 -> "7", -7 -> "N7".
std::string labelToken(int32_t l) {
  return l < 0 ? "N" + std::to_string(-int64_t(l)) : std::to_string(l);
}

/// Upper-case A-Z0-9_ text (Abaqus/CalculiX identifiers), no repeated or trailing underscores.
std::string safeName(const std::string& s) {
  std::string o;
  for (char c : s) {
    const unsigned char u = static_cast<unsigned char>(c);
    const char x = (u < 128 && std::isalnum(u)) ? char(std::toupper(u)) : '_';
    if (x == '_' && (o.empty() || o.back() == '_')) continue;
    o += x;
  }
  while (!o.empty() && o.back() == '_') o.pop_back();
  return o;
}

std::vector<int32_t> meshLabels(const TetMesh& m) {
  std::set<int32_t> s(m.tetLabels.begin(), m.tetLabels.end());
  return {s.begin(), s.end()};
}

/// Tet indices per label, in mesh order.
std::map<int32_t, std::vector<size_t>> tetsByLabel(const TetMesh& m) {
  std::map<int32_t, std::vector<size_t>> by;
  for (size_t t = 0; t < m.tets.size(); ++t) by[m.tetLabels[t]].push_back(t);
  return by;
}

/// Interface triangles grouped into patches (interfaces between two materials and per-material
/// outer boundaries), patches sorted by (labelA, labelB) with the boundary patches of a label
/// (labelB = -1) first.
std::map<PatchKey, std::vector<size_t>> patchesOf(const std::vector<InterfaceTriangle>& tris) {
  std::map<PatchKey, std::vector<size_t>> patches;
  for (size_t i = 0; i < tris.size(); ++i) patches[{tris[i].labelA, tris[i].labelB}].push_back(i);
  return patches;
}

/// "interface_1_2" or "boundary_1" (Gmsh physical names, STL solid names).
std::string patchName(const PatchKey& k) {
  if (k.second == kExteriorLabel) return "boundary_" + std::to_string(k.first);
  return "interface_" + std::to_string(k.first) + "_" + std::to_string(k.second);
}

Status ioError(const std::string& path) {
  return {ErrorCode::WriteFailed,
          "Cannot write '" + path + "': the disk may be full or the folder not writable."};
}

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

/// Collects VTK error/warning messages instead of letting VTK print them.
class VtkMessages {
 public:
  explicit VtkMessages(vtkObject* obj) {
    cb_->SetClientData(this);
    cb_->SetCallback([](vtkObject*, unsigned long, void* self, void* data) {
      auto* me = static_cast<VtkMessages*>(self);
      if (data && me->text.size() < 2000) me->text += std::string(static_cast<const char*>(data));
    });
    obj->AddObserver(vtkCommand::ErrorEvent, cb_);
    obj->AddObserver(vtkCommand::WarningEvent, cb_);
  }
  vtkCommand* command() { return cb_; }
  std::string text;

 private:
  vtkNew<vtkCallbackCommand> cb_;
};

// ---------------------------------------------------------------------------------------------
// VTK (.vtu, legacy .vtk)

vtkSmartPointer<vtkUnstructuredGrid> toGrid(const TetMesh& m, const ExportOptions& o, bool fieldData) {
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(vtkIdType(m.points.size()));
  for (size_t i = 0; i < m.points.size(); ++i) pts->SetPoint(vtkIdType(i), m.points[i].data());
  auto ug = vtkSmartPointer<vtkUnstructuredGrid>::New();
  ug->SetPoints(pts);
  ug->Allocate(vtkIdType(m.tets.size()));
  for (const auto& t : m.tets) {
    const vtkIdType ids[4] = {t[0], t[1], t[2], t[3]};
    ug->InsertNextCell(VTK_TETRA, 4, ids);
  }
  vtkNew<vtkIntArray> labels;
  labels->SetName("labels");
  labels->SetNumberOfValues(vtkIdType(m.tetLabels.size()));
  for (size_t i = 0; i < m.tetLabels.size(); ++i) labels->SetValue(vtkIdType(i), m.tetLabels[i]);
  ug->GetCellData()->AddArray(labels);
  ug->GetCellData()->SetActiveScalars("labels");
  if (!fieldData) return ug;
  vtkNew<vtkStringArray> space;
  space->SetName("SPACE");
  space->InsertNextValue("LPS");
  ug->GetFieldData()->AddArray(space);
  vtkNew<vtkIntArray> ids;
  ids->SetName("MaterialIds");
  vtkNew<vtkStringArray> names;
  names->SetName("MaterialNames");
  vtkNew<vtkDoubleArray> colors;
  colors->SetName("MaterialColors");
  colors->SetNumberOfComponents(3);
  for (int32_t l : meshLabels(m)) {
    const Material* mat = findMaterial(m.materials, l);
    ids->InsertNextValue(l);
    names->InsertNextValue(materialName(m, l));
    const auto c = mat ? mat->color : defaultLabelColor(l);
    colors->InsertNextTuple(c.data());
  }
  ug->GetFieldData()->AddArray(ids);
  ug->GetFieldData()->AddArray(names);
  ug->GetFieldData()->AddArray(colors);
  vtkNew<vtkStringArray> version;
  version->SetName("FEMesherVersion");
  version->InsertNextValue(FEMESHER_VERSION);
  ug->GetFieldData()->AddArray(version);
  if (!o.provenance.empty()) {
    vtkNew<vtkStringArray> prov;
    prov->SetName("Provenance");
    prov->InsertNextValue(o.provenance);
    ug->GetFieldData()->AddArray(prov);
  }
  return ug;
}

Status writeVtu(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  auto ug = toGrid(m, o, true);
  return writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkXMLUnstructuredGridWriter> w;
    VtkMessages messages(w);
    w->SetFileName(tmp.c_str());
    w->SetInputData(ug);
    w->SetDataModeToAppended();
    w->SetCompressorTypeToZLib();
    if (w->Write() != 1 || !messages.text.empty()) return ioError(path);
    return Status::ok();
  });
}

/// Legacy VTK 4.2 with Slicer's header convention ("3D Slicer output. SPACE=LPS"): read by Slicer,
/// ParaView and readers that do not understand string field data (meshio).
Status writeLegacyVtk(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  auto ug = toGrid(m, o, false);
  return writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkUnstructuredGridWriter> w;
    VtkMessages messages(w);
    w->SetFileName(tmp.c_str());
    w->SetInputData(ug);
    w->SetFileVersion(42);
    w->SetFileTypeToBinary();
    w->SetHeader("3D Slicer output. SPACE=LPS");
    if (w->Write() != 1 || !messages.text.empty()) return ioError(path);
    return Status::ok();
  });
}

// ---------------------------------------------------------------------------------------------
// Abaqus / CalculiX (.inp)

/// A real number in at most 20 characters (CalculiX reads each field of a data line as at most
/// 20 characters): the shortest text that reads back exactly when it fits (0.34, not
/// 0.34000000000000002), otherwise as many digits as fit.
std::string inpReal(double x) {
  char buf[64];
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, x);
    if (std::strtod(buf, nullptr) == x && std::strlen(buf) <= 20) return buf;
  }
  for (int digits = 17; digits >= 6; --digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, x);
    if (std::strlen(buf) <= 20) break;
  }
  return buf;
}

/// Abaqus C3D4 face numbering (1-based): S1 = 1-2-3, S2 = 1-4-2, S3 = 2-4-3, S4 = 3-4-1.
int abaqusFace(const std::array<int32_t, 4>& tet, const std::array<int32_t, 3>& tri) {
  static const int F[4][3] = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}};
  std::array<int32_t, 3> s = tri;
  std::sort(s.begin(), s.end());
  for (int f = 0; f < 4; ++f) {
    std::array<int32_t, 3> q{tet[F[f][0]], tet[F[f][1]], tet[F[f][2]]};
    std::sort(q.begin(), q.end());
    if (q == s) return f + 1;
  }
  return 0;
}

/// Writes `ids` (already 1-based) comma separated, at most 16 per data line.
void writeIdLines(std::FILE* f, const std::vector<size_t>& ids) {
  for (size_t i = 0; i < ids.size(); ++i) {
    const bool last = i + 1 == ids.size() || (i + 1) % 16 == 0;
    std::fprintf(f, "%zu%s", ids[i], last ? "\n" : ", ");
  }
}

/// Unique, safe Abaqus names of the element sets, one per label: M<label>_<NAME>, <= 46 chars
/// (so that "*SOLID SECTION, ELSET=<elset>, MATERIAL=MAT_<elset>" fits CalculiX's 132-character
/// lines and every name its 80-character limit).
std::map<int32_t, std::string> abaqusElsetNames(const TetMesh& m) {
  std::map<int32_t, std::string> elset;
  std::set<std::string> used;
  for (int32_t l : meshLabels(m)) {
    std::string base = "M" + labelToken(l);
    const std::string name = safeName(materialName(m, l));
    if (!name.empty()) base += "_" + name;
    if (base.size() > 40) base.resize(40);
    while (!base.empty() && base.back() == '_') base.pop_back();
    std::string n = base;
    for (int k = 2; used.count(n); ++k) n = base + "_" + std::to_string(k);
    used.insert(n);
    elset[l] = n;
  }
  return elset;
}

Status writeInp(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const auto byLabel = tetsByLabel(m);
  const auto tris = extractInterfaces(m);
  const auto patches = patchesOf(tris);
  const auto elset = abaqusElsetNames(m);
  return writeText(path, [&](std::FILE* f) {
    // CalculiX reads at most 132 characters per line.
    std::string heading = "FEMesher " FEMESHER_VERSION " multi-material tet mesh, LPS mm";
    if (!o.provenance.empty()) heading += ", " + oneLine(o.provenance);
    std::fprintf(f, "*HEADING\n%s\n", heading.substr(0, 130).c_str());
    std::fprintf(f,
                 "** Units: mm, N, MPa, tonne/mm^3. Model data only (no *STEP): *INCLUDE this file\n"
                 "** in an analysis deck and add boundary conditions, loads and steps there.\n"
                 "** Element sets (one per material), *SOLID SECTION and *MATERIAL per material:\n");
    for (const auto& [l, name] : elset) {
      std::fprintf(f, "**   label %d -> ELSET=%s\n", l, name.c_str());
      std::fprintf(f, "**     name '%s'\n", oneLine(materialName(m, l)).substr(0, 100).c_str());
    }
    std::fprintf(f,
                 "** NSET=BOUNDARY: nodes on the outer boundary. Element-based surfaces:\n"
                 "**   IF_<a>_<b> interface between labels a < b (faces of a's elements),\n"
                 "**   OUTER_<a> outer boundary of label a (negative labels written N<|a|>).\n");
    std::fprintf(f, "*NODE, NSET=ALLNODES\n");
    for (size_t i = 0; i < m.points.size(); ++i)
      std::fprintf(f, "%zu, %s, %s, %s\n", i + 1, inpReal(m.points[i][0]).c_str(),
                   inpReal(m.points[i][1]).c_str(), inpReal(m.points[i][2]).c_str());
    // Elements grouped by material; element id = 1-based index in the mesh (as in the .vtu).
    for (const auto& [l, tets] : byLabel) {
      std::fprintf(f, "*ELEMENT, TYPE=C3D4, ELSET=%s\n", elset.at(l).c_str());
      for (size_t t : tets)
        std::fprintf(f, "%zu, %d, %d, %d, %d\n", t + 1, m.tets[t][0] + 1, m.tets[t][1] + 1,
                     m.tets[t][2] + 1, m.tets[t][3] + 1);
    }
    // Outer boundary nodes.
    std::set<int32_t> boundary;
    for (const auto& t : tris)
      if (t.labelB == kExteriorLabel) boundary.insert(t.v.begin(), t.v.end());
    std::vector<size_t> ids;
    for (int32_t v : boundary) ids.push_back(size_t(v) + 1);
    std::fprintf(f, "*NSET, NSET=BOUNDARY\n");
    writeIdLines(f, ids);
    // Element-based surfaces, faces seen from labelA's elements.
    for (const auto& [key, list] : patches) {
      const std::string name = key.second == kExteriorLabel
                                   ? "OUTER_" + labelToken(key.first)
                                   : "IF_" + labelToken(key.first) + "_" + labelToken(key.second);
      std::fprintf(f, "*SURFACE, NAME=%s, TYPE=ELEMENT\n", name.c_str());
      for (size_t i : list) {
        const auto& t = tris[i];
        const int face = abaqusFace(m.tets[size_t(t.tetA)], t.v);
        if (face == 0)
          throw Error(ErrorCode::Internal, "Interface triangle is not a face of its tet (" + path + ")");
        std::fprintf(f, "%d, S%d\n", t.tetA + 1, face);
      }
    }
    for (const auto& [l, name] : elset) {
      const ElasticProperties& p = propsFor(o, l);
      std::fprintf(f, "*MATERIAL, NAME=MAT_%s\n*ELASTIC\n%s, %s\n*DENSITY\n%s\n", name.c_str(),
                   inpReal(p.youngsModulus).c_str(), inpReal(p.poissonRatio).c_str(),
                   inpReal(p.density).c_str());
      std::fprintf(f, "*SOLID SECTION, ELSET=%s, MATERIAL=MAT_%s\n", name.c_str(), name.c_str());
    }
  });
}

// ---------------------------------------------------------------------------------------------
// Gmsh MSH 4.1 ASCII (.msh)

/// Physical tags: a material's physical volume tag is its label when positive; labels <= 0 get
/// tags after the largest label. Surface tags start at 200000 (or beyond the volume tags).
/// Non-positive labels are recorded in a `$FEMesherLabels` section (ignored by other readers).
struct MshTags {
  std::map<int32_t, int> volumePhysical;
  int surfaceBase = 200000;
};

MshTags mshTags(const std::vector<int32_t>& labels) {
  MshTags t;
  int maxTag = 0;
  for (int32_t l : labels) maxTag = std::max<int>(maxTag, l);
  int next = maxTag + 1;
  for (int32_t l : labels) t.volumePhysical[l] = l > 0 ? int(l) : next++;
  const int top = std::max(maxTag, next - 1);
  if (top >= t.surfaceBase) t.surfaceBase = (top / 100000 + 1) * 100000;
  return t;
}

Status writeMsh(const TetMesh& m, const std::string& path, const ExportOptions&) {
  const auto byLabel = tetsByLabel(m);
  const auto labels = meshLabels(m);
  const auto tris = extractInterfaces(m);
  const auto patches = patchesOf(tris);
  const MshTags tags = mshTags(labels);
  // Geometric entities: volume v (1-based) per material, surface s (1-based) per patch.
  std::map<int32_t, int> volTag;
  for (int32_t l : labels) volTag[l] = int(volTag.size()) + 1;
  std::map<PatchKey, int> surfTag;
  for (const auto& kv : patches) surfTag[kv.first] = int(surfTag.size()) + 1;
  std::vector<int32_t> nonPositive;
  for (int32_t l : labels)
    if (l <= 0) nonPositive.push_back(l);
  return writeText(path, [&](std::FILE* f) {
    std::fprintf(f, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
    std::fprintf(f, "$PhysicalNames\n%zu\n", labels.size() + patches.size());
    for (int32_t l : labels)
      std::fprintf(f, "3 %d \"%s\"\n", tags.volumePhysical.at(l), oneLine(materialName(m, l), "\"").c_str());
    for (const auto& kv : patches)
      std::fprintf(f, "2 %d \"%s\"\n", tags.surfaceBase + surfTag.at(kv.first), patchName(kv.first).c_str());
    std::fprintf(f, "$EndPhysicalNames\n");
    if (!nonPositive.empty()) {
      std::fprintf(f, "$FEMesherLabels\n%zu\n", nonPositive.size());
      for (int32_t l : nonPositive) std::fprintf(f, "%d %d\n", tags.volumePhysical.at(l), l);
      std::fprintf(f, "$EndFEMesherLabels\n");
    }
    auto bbox = [&](auto&& forEachVertex, double* b) {
      b[0] = b[1] = b[2] = std::numeric_limits<double>::infinity();
      b[3] = b[4] = b[5] = -std::numeric_limits<double>::infinity();
      forEachVertex([&](int32_t v) {
        for (int k = 0; k < 3; ++k) {
          b[k] = std::min(b[k], m.points[size_t(v)][k]);
          b[3 + k] = std::max(b[3 + k], m.points[size_t(v)][k]);
        }
      });
    };
    std::fprintf(f, "$Entities\n0 0 %zu %zu\n", patches.size(), labels.size());
    for (const auto& [key, list] : patches) {
      double b[6];
      bbox([&](auto&& fn) { for (size_t i : list) for (int32_t v : tris[i].v) fn(v); }, b);
      std::fprintf(f, "%d %.17g %.17g %.17g %.17g %.17g %.17g 1 %d 0\n", surfTag.at(key), b[0], b[1],
                   b[2], b[3], b[4], b[5], tags.surfaceBase + surfTag.at(key));
    }
    for (int32_t l : labels) {
      std::vector<int> bounding;
      for (const auto& kv : patches)
        if (kv.first.first == l || kv.first.second == l) bounding.push_back(surfTag.at(kv.first));
      double b[6];
      bbox([&](auto&& fn) { for (size_t t : byLabel.at(l)) for (int32_t v : m.tets[t]) fn(v); }, b);
      std::fprintf(f, "%d %.17g %.17g %.17g %.17g %.17g %.17g 1 %d %zu", volTag.at(l), b[0], b[1],
                   b[2], b[3], b[4], b[5], tags.volumePhysical.at(l), bounding.size());
      for (int s : bounding) std::fprintf(f, " %d", s);
      std::fprintf(f, "\n");
    }
    std::fprintf(f, "$EndEntities\n");
    // Nodes in one block classified on the first volume (a non-parametric mesh: Gmsh and meshio
    // only need every node defined once); node tag = 1-based index in the mesh.
    const size_t np = m.points.size();
    std::fprintf(f, "$Nodes\n1 %zu 1 %zu\n3 %d 0 %zu\n", np, np, volTag.at(labels.front()), np);
    for (size_t i = 0; i < np; ++i) std::fprintf(f, "%zu\n", i + 1);
    for (size_t i = 0; i < np; ++i)
      std::fprintf(f, "%.17g %.17g %.17g\n", m.points[i][0], m.points[i][1], m.points[i][2]);
    std::fprintf(f, "$EndNodes\n");
    const size_t ne = tris.size() + m.tets.size();
    std::fprintf(f, "$Elements\n%zu %zu 1 %zu\n", patches.size() + labels.size(), ne, ne);
    size_t id = 1;
    for (const auto& [key, list] : patches) {
      std::fprintf(f, "2 %d 2 %zu\n", surfTag.at(key), list.size());
      for (size_t i : list)
        std::fprintf(f, "%zu %d %d %d\n", id++, tris[i].v[0] + 1, tris[i].v[1] + 1, tris[i].v[2] + 1);
    }
    for (int32_t l : labels) {
      const auto& list = byLabel.at(l);
      std::fprintf(f, "3 %d 4 %zu\n", volTag.at(l), list.size());
      for (size_t t : list)
        std::fprintf(f, "%zu %d %d %d %d\n", id++, m.tets[t][0] + 1, m.tets[t][1] + 1,
                     m.tets[t][2] + 1, m.tets[t][3] + 1);
    }
    std::fprintf(f, "$EndElements\n");
  });
}

// ---------------------------------------------------------------------------------------------
// Medit (.mesh)

Status writeMedit(const TetMesh& m, const std::string& path, const ExportOptions&) {
  const auto tris = extractInterfaces(m);
  const auto patches = patchesOf(tris);
  std::map<PatchKey, int> ref;
  for (const auto& kv : patches) ref[kv.first] = int(ref.size()) + 1;
  return writeText(path, [&](std::FILE* f) {
    std::fprintf(f, "MeshVersionFormatted 2\n\nDimension 3\n\n");
    std::fprintf(f, "# FEMesher %s, LPS mm. Tetrahedra ref = material label; Triangles ref:\n", FEMESHER_VERSION);
    for (const auto& [k, r] : ref) std::fprintf(f, "#   %d = %s\n", r, patchName(k).c_str());
    std::fprintf(f, "Vertices\n%zu\n", m.points.size());
    for (const auto& p : m.points) std::fprintf(f, "%.17g %.17g %.17g 0\n", p[0], p[1], p[2]);
    std::fprintf(f, "\nTriangles\n%zu\n", tris.size());
    for (const auto& [k, list] : patches)
      for (size_t i : list)
        std::fprintf(f, "%d %d %d %d\n", tris[i].v[0] + 1, tris[i].v[1] + 1, tris[i].v[2] + 1, ref.at(k));
    std::fprintf(f, "\nTetrahedra\n%zu\n", m.tets.size());
    for (size_t t = 0; t < m.tets.size(); ++t)
      std::fprintf(f, "%d %d %d %d %d\n", m.tets[t][0] + 1, m.tets[t][1] + 1, m.tets[t][2] + 1,
                   m.tets[t][3] + 1, m.tetLabels[t]);
    std::fprintf(f, "\nEnd\n");
  });
}

// ---------------------------------------------------------------------------------------------
// FEBio 2.5 (.feb)

std::string xmlEscape(const std::string& s) {
  std::string o;
  for (char c : oneLine(s)) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else if (c == '"') o += "&quot;";
    else o += c;
  }
  return o;
}

Status writeFeb(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const auto byLabel = tetsByLabel(m);
  const auto tris = extractInterfaces(m);
  const auto patches = patchesOf(tris);
  const auto elset = abaqusElsetNames(m);
  return writeText(path, [&](std::FILE* f) {
    // ISO-8859-1: any byte sequence in a material name keeps the file well-formed.
    std::fprintf(f, "<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>\n");
    std::fprintf(f, "<!-- FEMesher %s: LPS mm, mm-N-s-MPa units; neo-Hookean materials from E and nu.\n"
                    "     Elements are numbered 1..N per domain in file order; add Boundary, Loads,\n"
                    "     Control and Step sections for an analysis. -->\n", FEMESHER_VERSION);
    std::fprintf(f, "<febio_spec version=\"2.5\">\n\t<Module type=\"solid\"/>\n");
    std::fprintf(f, "\t<Globals>\n\t\t<Constants>\n\t\t\t<T>0</T>\n\t\t\t<R>0</R>\n\t\t\t<Fc>0</Fc>\n"
                    "\t\t</Constants>\n\t</Globals>\n\t<Material>\n");
    std::map<int32_t, int> mid;
    for (const auto& [l, tets] : byLabel) {
      const ElasticProperties& p = propsFor(o, l);
      const int id = int(mid.size()) + 1;
      mid[l] = id;
      std::fprintf(f, "\t\t<material id=\"%d\" name=\"%s\" type=\"neo-Hookean\">\n", id,
                   xmlEscape(materialName(m, l)).c_str());
      std::fprintf(f, "\t\t\t<density>%.15g</density>\n\t\t\t<E>%.15g</E>\n\t\t\t<v>%.15g</v>\n",
                   p.density, p.youngsModulus, p.poissonRatio);
      std::fprintf(f, "\t\t</material>\n");
    }
    std::fprintf(f, "\t</Material>\n\t<Geometry>\n\t\t<Nodes name=\"AllNodes\">\n");
    for (size_t i = 0; i < m.points.size(); ++i)
      std::fprintf(f, "\t\t\t<node id=\"%zu\">%.17g,%.17g,%.17g</node>\n", i + 1, m.points[i][0],
                   m.points[i][1], m.points[i][2]);
    std::fprintf(f, "\t\t</Nodes>\n");
    size_t eid = 1;
    for (const auto& [l, tets] : byLabel) {
      std::fprintf(f, "\t\t<Elements type=\"tet4\" mat=\"%d\" name=\"%s\">\n", mid.at(l), elset.at(l).c_str());
      for (size_t t : tets)
        std::fprintf(f, "\t\t\t<elem id=\"%zu\">%d,%d,%d,%d</elem>\n", eid++, m.tets[t][0] + 1,
                     m.tets[t][1] + 1, m.tets[t][2] + 1, m.tets[t][3] + 1);
      std::fprintf(f, "\t\t</Elements>\n");
    }
    for (const auto& [key, list] : patches) {
      std::fprintf(f, "\t\t<Surface name=\"%s\">\n", patchName(key).c_str());
      size_t fid = 1;
      for (size_t i : list)
        std::fprintf(f, "\t\t\t<tri3 id=\"%zu\">%d,%d,%d</tri3>\n", fid++, tris[i].v[0] + 1,
                     tris[i].v[1] + 1, tris[i].v[2] + 1);
      std::fprintf(f, "\t\t</Surface>\n");
    }
    std::fprintf(f, "\t</Geometry>\n</febio_spec>\n");
  });
}

// ---------------------------------------------------------------------------------------------
// ASCII STL (.stl)

Status writeStl(const TetMesh& m, const std::string& path, const ExportOptions&) {
  const auto tris = extractInterfaces(m);
  const auto patches = patchesOf(tris);
  return writeText(path, [&](std::FILE* f) {
    for (const auto& [key, list] : patches) {
      const std::string name = patchName(key);
      std::fprintf(f, "solid %s\n", name.c_str());
      for (size_t i : list) {
        const Vec3 &a = m.points[size_t(tris[i].v[0])], &b = m.points[size_t(tris[i].v[1])],
                   &c = m.points[size_t(tris[i].v[2])];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (len > 0)
          for (double& x : n) x /= len;
        std::fprintf(f, "  facet normal %.9g %.9g %.9g\n    outer loop\n", n[0], n[1], n[2]);
        for (const Vec3* p : {&a, &b, &c})
          std::fprintf(f, "      vertex %.17g %.17g %.17g\n", (*p)[0], (*p)[1], (*p)[2]);
        std::fprintf(f, "    endloop\n  endfacet\n");
      }
      std::fprintf(f, "endsolid %s\n", name.c_str());
    }
  });
}

// ---------------------------------------------------------------------------------------------
// Readers

Result<TetMesh> fail(ErrorCode code, const std::string& path, const std::string& what) {
  return Result<TetMesh>(code, "Cannot read mesh '" + path + "': " + what);
}

/// Checks indices and sizes of a mesh just read; fills materials (names from `names`).
Result<TetMesh> finishRead(TetMesh m, const std::string& path, const std::map<int32_t, std::string>& names,
                           const std::map<int32_t, std::array<double, 3>>& colors = {}) {
  if (m.tets.empty()) return fail(ErrorCode::CorruptFile, path, "it holds no tetrahedra.");
  if (m.tets.size() != m.tetLabels.size())
    return fail(ErrorCode::CorruptFile, path, "the number of labels differs from the number of tetrahedra.");
  for (const auto& t : m.tets)
    for (int32_t v : t)
      if (v < 0 || size_t(v) >= m.points.size())
        return fail(ErrorCode::CorruptFile, path,
                    "a tetrahedron refers to vertex " + std::to_string(int64_t(v) + 1) + " but there are " +
                        std::to_string(m.points.size()) + " vertices.");
  for (const auto& p : m.points)
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      return fail(ErrorCode::CorruptFile, path, "a vertex has a non-finite coordinate.");
  for (int32_t l : meshLabels(m)) {
    Material mat{l, "label " + std::to_string(l), defaultLabelColor(l)};
    if (auto it = names.find(l); it != names.end() && !it->second.empty()) mat.name = it->second;
    if (auto it = colors.find(l); it != colors.end()) mat.color = it->second;
    m.materials.push_back(mat);
  }
  return m;
}

Result<TetMesh> gridToMesh(vtkUnstructuredGrid* ug, const std::string& path) {
  if (!ug || ug->GetNumberOfCells() == 0) return fail(ErrorCode::CorruptFile, path, "it holds no cells.");
  vtkDataArray* labels = ug->GetCellData()->GetArray("labels");
  if (!labels || labels->GetNumberOfTuples() != ug->GetNumberOfCells())
    return fail(ErrorCode::UnreadableFile, path,
                "it has no cell array 'labels' with one material id per cell (not a labelled mesh; "
                "write it with FEMesher or add an integer cell array named 'labels').");
  TetMesh m;
  m.points.resize(size_t(ug->GetNumberOfPoints()));
  for (vtkIdType i = 0; i < ug->GetNumberOfPoints(); ++i) ug->GetPoint(i, m.points[size_t(i)].data());
  m.tets.reserve(size_t(ug->GetNumberOfCells()));
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < ug->GetNumberOfCells(); ++c) {
    if (ug->GetCellType(c) != VTK_TETRA)
      return fail(ErrorCode::UnreadableFile, path,
                  "cell " + std::to_string(c) + " is not a linear tetrahedron (VTK type " +
                      std::to_string(ug->GetCellType(c)) + ").");
    ug->GetCellPoints(c, ids);
    m.tets.push_back({int32_t(ids->GetId(0)), int32_t(ids->GetId(1)), int32_t(ids->GetId(2)),
                      int32_t(ids->GetId(3))});
    const double v = labels->GetTuple1(c);
    if (v != std::floor(v) || std::fabs(v) > 2147483647.0)
      return fail(ErrorCode::CorruptFile, path, "cell array 'labels' holds a non-integer value.");
    m.tetLabels.push_back(int32_t(v));
  }
  std::map<int32_t, std::string> names;
  std::map<int32_t, std::array<double, 3>> colors;
  vtkFieldData* fd = ug->GetFieldData();
  auto* idArr = vtkIntArray::SafeDownCast(fd ? fd->GetAbstractArray("MaterialIds") : nullptr);
  auto* nameArr = vtkStringArray::SafeDownCast(fd ? fd->GetAbstractArray("MaterialNames") : nullptr);
  auto* colorArr = vtkDataArray::SafeDownCast(fd ? fd->GetAbstractArray("MaterialColors") : nullptr);
  if (idArr)
    for (vtkIdType k = 0; k < idArr->GetNumberOfValues(); ++k) {
      if (nameArr && k < nameArr->GetNumberOfValues()) names[idArr->GetValue(k)] = nameArr->GetValue(k);
      if (colorArr && colorArr->GetNumberOfComponents() == 3 && k < colorArr->GetNumberOfTuples()) {
        double c[3];
        colorArr->GetTuple(k, c);
        colors[idArr->GetValue(k)] = {c[0], c[1], c[2]};
      }
    }
  return finishRead(std::move(m), path, names, colors);
}

Result<TetMesh> readVtu(const std::string& path) {
  vtkNew<vtkXMLUnstructuredGridReader> r;
  VtkMessages messages(r);
  r->SetReaderErrorObserver(messages.command());
  r->SetParserErrorObserver(messages.command());  // the XML parser's own errors (damaged data)
  if (!r->CanReadFile(path.c_str()))
    return fail(ErrorCode::UnreadableFile, path, "it is not a VTK XML unstructured grid (.vtu).");
  r->SetFileName(path.c_str());
  r->Update();
  if (!messages.text.empty() || r->GetErrorCode() != 0)
    return fail(ErrorCode::CorruptFile, path,
                "VTK could not decode it (truncated or damaged?)" +
                    (messages.text.empty() ? std::string(".") : ": " + oneLine(messages.text.substr(0, 300))));
  return gridToMesh(r->GetOutput(), path);
}

Result<TetMesh> readLegacyVtk(const std::string& path) {
  vtkNew<vtkUnstructuredGridReader> r;
  VtkMessages messages(r);
  r->SetFileName(path.c_str());
  if (!r->IsFileUnstructuredGrid())
    return fail(ErrorCode::UnreadableFile, path, "it is not a legacy VTK unstructured grid.");
  r->Update();
  if (!messages.text.empty())
    return fail(ErrorCode::CorruptFile, path,
                "VTK could not decode it: " + oneLine(messages.text.substr(0, 300)));
  return gridToMesh(r->GetOutput(), path);
}

/// Whitespace-separated tokens with section-aware error messages.
class Tokens {
 public:
  Tokens(std::istream& in, std::string path) : in_(in), path_(std::move(path)) {}
  bool next(std::string& w) { return bool(in_ >> w); }
  template <class T>
  T get(const char* what) {
    T v{};
    if (!(in_ >> v))
      throw Error(ErrorCode::CorruptFile, "Cannot read mesh '" + path_ + "': truncated or malformed " +
                                              std::string(what) + ".");
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
  std::istream& stream() { return in_; }

 private:
  std::istream& in_;
  std::string path_;
};

Result<TetMesh> readMedit(const std::string& path) {
  std::ifstream in(path);
  if (!in) return fail(ErrorCode::UnreadableFile, path, "the file cannot be opened.");
  Tokens tok(in, path);
  TetMesh m;
  std::string w;
  bool sawHeader = false;
  // Element keywords and their vertex count (all followed by a ref).
  static const std::map<std::string, int> kElements = {
      {"Edges", 2}, {"Triangles", 3}, {"Quadrilaterals", 4}, {"Tetrahedra", 4},
      {"Hexahedra", 8}, {"Prisms", 6}, {"Pyramids", 5}};
  static const std::map<std::string, int> kLists = {
      {"Corners", 1}, {"RequiredVertices", 1}, {"Ridges", 1}, {"RequiredEdges", 1},
      {"RequiredTriangles", 1}, {"Normals", 3}, {"Tangents", 3}, {"NormalAtVertices", 2},
      {"TangentAtVertices", 2}, {"NormalAtTriangleVertices", 3}};
  while (tok.next(w)) {
    if (w[0] == '#') {
      tok.skipLine();
      continue;
    }
    if (w == "MeshVersionFormatted") {
      const int v = tok.get<int>("MeshVersionFormatted");
      if (v < 1 || v > 2)
        return fail(ErrorCode::UnreadableFile, path, "Medit version " + std::to_string(v) +
                                                         " is not supported (ASCII version 1 or 2 expected).");
      sawHeader = true;
    } else if (w == "Dimension") {
      const int d = tok.get<int>("Dimension");
      if (d != 3) return fail(ErrorCode::UnreadableFile, path, "it is a " + std::to_string(d) + "-D mesh (3-D expected).");
    } else if (w == "Vertices") {
      const auto n = tok.get<long long>("Vertices count");
      if (n < 0) return fail(ErrorCode::CorruptFile, path, "negative vertex count.");
      m.points.resize(size_t(n));
      for (auto& p : m.points) {
        p[0] = tok.get<double>("Vertices");
        p[1] = tok.get<double>("Vertices");
        p[2] = tok.get<double>("Vertices");
        tok.get<long long>("Vertices reference");
      }
    } else if (w == "Tetrahedra") {
      const auto n = tok.get<long long>("Tetrahedra count");
      if (n < 0) return fail(ErrorCode::CorruptFile, path, "negative tetrahedron count.");
      m.tets.reserve(size_t(n));
      for (long long i = 0; i < n; ++i) {
        std::array<int32_t, 4> t;
        for (auto& x : t) x = int32_t(tok.get<long long>("Tetrahedra") - 1);
        m.tets.push_back(t);
        m.tetLabels.push_back(int32_t(tok.get<long long>("Tetrahedra reference")));
      }
    } else if (auto e = kElements.find(w); e != kElements.end()) {
      const auto n = tok.get<long long>(w.c_str());
      for (long long i = 0; i < n * (e->second + 1); ++i) tok.get<long long>(w.c_str());
    } else if (auto l = kLists.find(w); l != kLists.end()) {
      const auto n = tok.get<long long>(w.c_str());
      for (long long i = 0; i < n * l->second; ++i) tok.get<double>(w.c_str());
    } else if (w == "End") {
      break;
    } else {
      return fail(ErrorCode::UnreadableFile, path,
                  "unknown Medit keyword '" + w.substr(0, 40) + "' (ASCII .mesh with Vertices and Tetrahedra expected).");
    }
  }
  if (!sawHeader)
    return fail(ErrorCode::UnreadableFile, path, "no 'MeshVersionFormatted' header (not an ASCII Medit mesh).");
  return finishRead(std::move(m), path, {});
}

int mshNodesPerElement(int type) {
  switch (type) {
    case 15: return 1;   // point
    case 1: return 2;    // line
    case 2: return 3;    // triangle
    case 3: return 4;    // quadrangle
    case 4: return 4;    // tetrahedron
    case 5: return 8;    // hexahedron
    case 6: return 6;    // prism
    case 7: return 5;    // pyramid
    case 8: return 3;    // 3-node line
    case 9: return 6;    // 6-node triangle
    case 11: return 10;  // 10-node tetrahedron
    default: return -1;
  }
}

Result<TetMesh> readMsh(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(ErrorCode::UnreadableFile, path, "the file cannot be opened.");
  Tokens tok(in, path);
  TetMesh m;
  std::map<int, int> volumePhysical;        // volume entity tag -> first physical tag
  std::map<int, std::string> physNames;     // dim-3 physical tag -> name
  std::map<int, int32_t> physToLabel;       // from $FEMesherLabels
  std::unordered_map<long long, int32_t> nodeIndex;
  std::vector<std::pair<std::array<long long, 4>, int>> rawTets;  // node tags, volume entity
  bool sawFormat = false, sawNodes = false;
  std::string w;
  while (tok.next(w)) {
    if (w.empty() || w[0] != '$')
      return fail(ErrorCode::CorruptFile, path, "unexpected text '" + w.substr(0, 40) + "' outside a section.");
    const std::string section = w.substr(1);
    if (section == "MeshFormat") {
      const std::string version = tok.get<std::string>("$MeshFormat");
      const int fileType = tok.get<int>("$MeshFormat");
      tok.get<int>("$MeshFormat");
      if (version.rfind("4.1", 0) != 0)
        return fail(ErrorCode::UnreadableFile, path,
                    "MSH version " + version + " is not supported; re-save it as MSH 4.1 "
                    "(gmsh FILE -0 -format msh41 -o OUT.msh).");
      if (fileType != 0)
        return fail(ErrorCode::UnreadableFile, path,
                    "binary MSH is not supported; re-save it as ASCII MSH 4.1 (gmsh FILE -0 -format msh41 -o OUT.msh).");
      sawFormat = true;
    } else if (!sawFormat) {
      return fail(ErrorCode::UnreadableFile, path, "it does not start with $MeshFormat (not a Gmsh mesh).");
    } else if (section == "PhysicalNames") {
      const auto n = tok.get<long long>("$PhysicalNames");
      tok.skipLine();
      for (long long i = 0; i < n; ++i) {
        std::istringstream s(tok.line());
        int dim = 0, tag = 0;
        if (!(s >> dim >> tag)) return fail(ErrorCode::CorruptFile, path, "malformed $PhysicalNames.");
        std::string rest;
        std::getline(s, rest);
        const auto a = rest.find('"'), b = rest.rfind('"');
        if (dim == 3 && a != std::string::npos && b > a) physNames[tag] = rest.substr(a + 1, b - a - 1);
      }
    } else if (section == "FEMesherLabels") {
      const auto n = tok.get<long long>("$FEMesherLabels");
      for (long long i = 0; i < n; ++i) {
        const int tag = tok.get<int>("$FEMesherLabels");
        physToLabel[tag] = tok.get<int32_t>("$FEMesherLabels");
      }
    } else if (section == "Entities") {
      long long count[4];
      for (auto& c : count) c = tok.get<long long>("$Entities");
      for (int d = 0; d < 4; ++d)
        for (long long i = 0; i < count[d]; ++i) {
          const int tag = tok.get<int>("$Entities");
          for (int k = 0; k < (d == 0 ? 3 : 6); ++k) tok.get<double>("$Entities");
          const auto nphys = tok.get<long long>("$Entities");
          for (long long k = 0; k < nphys; ++k) {
            const int p = tok.get<int>("$Entities");
            if (d == 3 && k == 0) volumePhysical[tag] = p;
          }
          if (d > 0) {
            const auto nb = tok.get<long long>("$Entities");
            for (long long k = 0; k < nb; ++k) tok.get<int>("$Entities");
          }
        }
    } else if (section == "Nodes") {
      const auto blocks = tok.get<long long>("$Nodes");
      const auto total = tok.get<long long>("$Nodes");
      tok.get<long long>("$Nodes");
      tok.get<long long>("$Nodes");
      if (total < 0) return fail(ErrorCode::CorruptFile, path, "negative node count.");
      m.points.reserve(size_t(total));
      for (long long b = 0; b < blocks; ++b) {
        tok.get<int>("$Nodes");
        tok.get<int>("$Nodes");
        const int parametric = tok.get<int>("$Nodes");
        const auto n = tok.get<long long>("$Nodes");
        if (parametric != 0)
          return fail(ErrorCode::UnreadableFile, path, "parametric nodes are not supported.");
        std::vector<long long> tags(size_t(std::max(0LL, n)));
        for (auto& t : tags) t = tok.get<long long>("$Nodes");
        for (long long t : tags) {
          Vec3 p;
          for (double& x : p) x = tok.get<double>("$Nodes");
          if (!nodeIndex.emplace(t, int32_t(m.points.size())).second)
            return fail(ErrorCode::CorruptFile, path, "node " + std::to_string(t) + " is defined twice.");
          m.points.push_back(p);
        }
      }
      if (m.points.size() != size_t(total))
        return fail(ErrorCode::CorruptFile, path, "$Nodes announces " + std::to_string(total) +
                                                      " nodes but holds " + std::to_string(m.points.size()) + ".");
      sawNodes = true;
    } else if (section == "Elements") {
      const auto blocks = tok.get<long long>("$Elements");
      for (int k = 0; k < 3; ++k) tok.get<long long>("$Elements");
      for (long long b = 0; b < blocks; ++b) {
        const int dim = tok.get<int>("$Elements");
        const int tag = tok.get<int>("$Elements");
        const int type = tok.get<int>("$Elements");
        const auto n = tok.get<long long>("$Elements");
        const int nn = mshNodesPerElement(type);
        if (nn < 0)
          return fail(ErrorCode::UnreadableFile, path, "element type " + std::to_string(type) + " is not supported.");
        if (dim == 3 && type != 4)
          return fail(ErrorCode::UnreadableFile, path,
                      "it has volume elements that are not linear tetrahedra (Gmsh type " +
                          std::to_string(type) + ").");
        for (long long i = 0; i < n; ++i) {
          tok.get<long long>("$Elements");
          std::array<long long, 4> v{};
          for (int k = 0; k < nn; ++k) {
            const long long x = tok.get<long long>("$Elements");
            if (k < 4) v[size_t(k)] = x;
          }
          if (type == 4) rawTets.push_back({v, tag});
        }
      }
    } else {
      // Unknown section ($Comments, $NodeData, ...): skip to its end marker.
      const std::string end = "$End" + section;
      bool found = false;
      while (tok.next(w))
        if (w == end) {
          found = true;
          break;
        }
      if (!found) return fail(ErrorCode::CorruptFile, path, "section $" + section + " has no " + end + ".");
      continue;
    }
    if (!tok.next(w) || w != "$End" + section)
      return fail(ErrorCode::CorruptFile, path, "section $" + section + " does not end with $End" + section +
                                                    " (truncated file or counts that do not match the data).");
  }
  if (!sawFormat) return fail(ErrorCode::UnreadableFile, path, "it is empty or not a Gmsh mesh.");
  if (!sawNodes) return fail(ErrorCode::CorruptFile, path, "it has no $Nodes section.");
  for (const auto& [v, entity] : rawTets) {
    std::array<int32_t, 4> t;
    for (int k = 0; k < 4; ++k) {
      auto it = nodeIndex.find(v[size_t(k)]);
      if (it == nodeIndex.end())
        return fail(ErrorCode::CorruptFile, path, "a tetrahedron uses undefined node " + std::to_string(v[size_t(k)]) + ".");
      t[size_t(k)] = it->second;
    }
    m.tets.push_back(t);
    auto p = volumePhysical.find(entity);
    const int phys = p != volumePhysical.end() ? p->second : entity;
    auto l = physToLabel.find(phys);
    m.tetLabels.push_back(l != physToLabel.end() ? l->second : int32_t(phys));
  }
  std::map<int32_t, std::string> names;
  for (const auto& [tag, name] : physNames) {
    auto l = physToLabel.find(tag);
    names[l != physToLabel.end() ? l->second : int32_t(tag)] = name;
  }
  return finishRead(std::move(m), path, names);
}

Status checkMesh(const TetMesh& mesh, const std::string& path) {
  if (mesh.tets.empty())
    return {ErrorCode::InvalidArgument, "Cannot write '" + path + "': the mesh has no tetrahedra."};
  if (mesh.tetLabels.size() != mesh.tets.size())
    return {ErrorCode::Internal, "Cannot write '" + path + "': the mesh has " +
                                     std::to_string(mesh.tetLabels.size()) + " labels for " +
                                     std::to_string(mesh.tets.size()) + " tetrahedra."};
  for (const auto& t : mesh.tets)
    for (int32_t v : t)
      if (v < 0 || size_t(v) >= mesh.points.size())
        return {ErrorCode::Internal, "Cannot write '" + path + "': a tetrahedron refers to a missing vertex."};
  return Status::ok();
}

}  // namespace

ExportOptions exportOptionsFrom(const MeshingParameters& params) {
  ExportOptions o;
  o.defaultMaterial = params.defaultMaterial;
  o.materialProperties = params.materialProperties;
  return o;
}

std::vector<std::string> supportedMeshExtensions() {
  return {".vtu", ".vtk", ".inp", ".msh", ".mesh", ".feb", ".stl"};
}

Status writeMesh(const TetMesh& mesh, const std::string& path, const ExportOptions& options) {
  const std::string ext = fileExtension(path);
  using Writer = Status (*)(const TetMesh&, const std::string&, const ExportOptions&);
  static const std::map<std::string, Writer> writers = {
      {".vtu", writeVtu}, {".vtk", writeLegacyVtk}, {".inp", writeInp}, {".msh", writeMsh},
      {".mesh", writeMedit}, {".feb", writeFeb}, {".stl", writeStl}};
  const auto it = writers.find(ext);
  if (it == writers.end()) {
    std::string list;
    for (const auto& e : supportedMeshExtensions()) list += (list.empty() ? "" : " ") + e;
    return {ErrorCode::InvalidArgument,
            "Cannot write '" + path + "': " +
                (ext.empty() ? std::string("the file name has no extension") : "unknown extension '" + ext + "'") +
                ". Supported mesh formats: " + list + "."};
  }
  if (Status s = checkMesh(mesh, path); !s) return s;
  try {
    return it->second(mesh, path, options);
  } catch (const Error& e) {
    return e.status();
  } catch (const std::exception& e) {
    return {ErrorCode::WriteFailed, "Cannot write '" + path + "': " + e.what()};
  }
}

Result<TetMesh> readMesh(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    return fail(ErrorCode::FileNotFound, path, "the file does not exist.");
  if (std::filesystem::is_directory(path, ec))
    return fail(ErrorCode::UnreadableFile, path, "it is a folder, not a mesh file.");
  const std::string ext = fileExtension(path);
  try {
    if (ext == ".vtu") return readVtu(path);
    if (ext == ".vtk") return readLegacyVtk(path);
    if (ext == ".mesh") return readMedit(path);
    if (ext == ".msh") return readMsh(path);
  } catch (const Error& e) {
    return Result<TetMesh>(e.status());
  } catch (const std::exception& e) {
    return fail(ErrorCode::CorruptFile, path, e.what());
  }
  return fail(ErrorCode::UnreadableFile, path,
              "unsupported extension '" + ext + "'; FEMesher reads .vtu, .vtk, .msh (4.1 ASCII) and .mesh (Medit).");
}

}  // namespace femesher
