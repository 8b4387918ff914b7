// SPDX-License-Identifier: GPL-3.0-or-later
// The public mesh I/O entry points: the extension picks a format of MeshFormats.h.
#include <femesher/io/MeshFormats.h>
#include <femesher/io/MeshIO.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>

namespace femesher {

namespace {

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

/// The contact faces and node sets of `options` must belong to `mesh` (they are made for the mesh
/// a run returned: PipelineResult::contacts, ::boxNodeSets).
Status checkExportTables(const TetMesh& mesh, const std::string& path, const ExportOptions& o) {
  const Status bad(ErrorCode::Internal,
                   "Cannot write '" + path + "': the contact pairs or node sets given with the "
                   "mesh do not belong to it (export the mesh together with its run's tables).");
  for (const auto& c : o.contacts) {
    if (c.facesA.size() != c.facesB.size()) return bad;
    for (const auto* faces : {&c.facesA, &c.facesB})
      for (const ElementFace& f : *faces)
        if (f.tet < 0 || size_t(f.tet) >= mesh.tets.size() || f.opposite < 0 || f.opposite > 3 ||
            mesh.tetLabels[size_t(f.tet)] != (faces == &c.facesA ? c.labelA : c.labelB))
          return bad;
  }
  for (const auto& n : o.nodeSets)
    for (int32_t v : n.nodes)
      if (v < 0 || size_t(v) >= mesh.points.size()) return bad;
  return Status::ok();
}

}  // namespace

ExportOptions exportOptionsFrom(const MeshingParameters& params) {
  ExportOptions o;
  o.defaultMaterial = params.defaultMaterial;
  o.materialProperties = params.materialProperties;
  const ElasticProperties builtIn;
  o.defaultMaterialGiven = params.defaultMaterial.youngsModulus != builtIn.youngsModulus ||
                           params.defaultMaterial.poissonRatio != builtIn.poissonRatio ||
                           params.defaultMaterial.density != builtIn.density;
  o.elementOrder = params.elementOrder;
  return o;
}

std::string defaultPropertiesWarning(const TetMesh& mesh, const std::string& path,
                                     const ExportOptions& options) {
  const std::string ext = fileExtension(path);
  if ((ext != ".inp" && ext != ".feb") || options.defaultMaterialGiven) return {};
  std::string list;
  size_t count = 0;
  for (int32_t l : meshio::meshLabels(mesh)) {
    if (options.materialProperties.count(l)) continue;
    list += (list.empty() ? "" : ", ") + std::string("label ") + std::to_string(l) + " (" +
            meshio::oneLine(meshio::materialName(mesh, l)) + ")";
    ++count;
  }
  if (count == 0) return {};
  const ElasticProperties& d = options.defaultMaterial;
  char values[128];
  std::snprintf(values, sizeof values, "E = %g MPa, nu = %g, density = %g t/mm^3", d.youngsModulus,
                d.poissonRatio, d.density);
  return "'" + path + "': " + std::to_string(count) +
         (count == 1 ? " material has no properties of yours and gets"
                     : " materials have no properties of yours and get") +
         " the built-in default " + values + ": " + list +
         ". Set them with --set material.<label>.E=... (and .nu, .density), default.E=... for "
         "all, or the panel's material table.";
}

std::vector<std::string> supportedMeshExtensions() {
  return {".vtu", ".vtk", ".inp", ".msh", ".mesh", ".feb", ".stl"};
}

Status checkExportable(const std::string& path, const ExportOptions& options) {
  const std::string ext = fileExtension(path);
  const auto exts = supportedMeshExtensions();
  std::string list;
  for (const auto& e : exts) list += (list.empty() ? "" : " ") + e;
  if (std::find(exts.begin(), exts.end(), ext) == exts.end())
    return {ErrorCode::InvalidArgument,
            "Cannot write '" + path + "': " +
                (ext.empty() ? std::string("the file name has no extension") : "unknown extension '" + ext + "'") +
                ". Supported mesh formats: " + list + "."};
  if (options.elementOrder != 1 && options.elementOrder != 2)
    return {ErrorCode::InvalidArgument,
            "Cannot write '" + path + "': element_order " + std::to_string(options.elementOrder) +
                " is not supported; use 1 (4-node tets) or 2 (10-node tets)."};
  if (options.elementOrder == 2 && (ext == ".mesh" || ext == ".stl"))
    return {ErrorCode::InvalidArgument,
            "Cannot write '" + path + "': " + (ext == ".mesh" ? "Medit .mesh" : "STL") +
                " cannot hold 10-node tetrahedra (element_order=2). Write .inp, .msh, .vtu, .vtk or "
                ".feb for second order, or set element_order=1."};
  return Status::ok();
}

Status writeMesh(const TetMesh& mesh, const std::string& path, const ExportOptions& options) {
  const std::string ext = fileExtension(path);
  if (Status s = checkExportable(path, options); !s) return s;
  using Writer = Status (*)(const TetMesh&, const std::string&, const ExportOptions&);
  using namespace meshio;
  static const std::map<std::string, Writer> writers = {
      {".vtu", writeVtu}, {".vtk", writeLegacyVtk}, {".inp", writeInp}, {".msh", writeMsh},
      {".mesh", writeMedit}, {".feb", writeFeb}, {".stl", writeStl}};
  const auto it = writers.find(ext);
  if (it == writers.end())
    return {ErrorCode::Internal, "Cannot write '" + path + "': no writer for '" + ext + "'."};
  if (Status s = checkMesh(mesh, path); !s) return s;
  if (Status s = checkExportTables(mesh, path, options); !s) return s;
  try {
    return it->second(mesh, path, options);
  } catch (const Error& e) {
    return e.status();
  } catch (const std::exception& e) {
    return {ErrorCode::WriteFailed, "Cannot write '" + path + "': " + e.what()};
  }
}

namespace {

/// The corner mesh of a file of 10-node tets: corners renumbered, mid-edge nodes by edge.
Result<MeshFile> cornerMesh(TetMesh m, const std::vector<std::array<int32_t, 6>>& mids,
                            const std::string& path) {
  using meshio::fail;
  MeshFile out;
  const bool anyQuadratic =
      std::any_of(mids.begin(), mids.end(), [](const auto& e) { return e[0] >= 0; });
  if (!anyQuadratic) {
    out.mesh = std::move(m);
    return out;
  }
  if (mids.size() != m.tets.size() || std::any_of(mids.begin(), mids.end(), [](const auto& e) {
        return std::any_of(e.begin(), e.end(), [](int32_t v) { return v < 0; });
      }))
    return Result<MeshFile>(
        fail(ErrorCode::UnreadableFile, path,
             "it mixes 4-node and 10-node tetrahedra; FEMesher reads meshes of one "
             "element order.")
            .status());
  std::vector<int32_t> corner(m.points.size(), -1);
  std::vector<char> isMid(m.points.size(), 0);
  for (const auto& e : mids)
    for (int32_t v : e) isMid[size_t(v)] = 1;
  TetMesh& c = out.mesh;
  for (const auto& t : m.tets)
    for (int32_t v : t) {
      if (isMid[size_t(v)])
        return Result<MeshFile>(fail(ErrorCode::CorruptFile, path,
                                     "node " + std::to_string(v + 1) +
                                         " is both a corner and a "
                                         "mid-edge node of 10-node tetrahedra.")
                                    .status());
      corner[size_t(v)] = 0;
    }
  for (size_t v = 0; v < corner.size(); ++v)  // corners keep their order in the file
    if (corner[v] == 0) {
      corner[v] = int32_t(c.points.size());
      c.points.push_back(m.points[v]);
    }
  for (auto& t : m.tets)
    for (int32_t& v : t) v = corner[size_t(v)];
  c.tets = std::move(m.tets);
  c.tetLabels = std::move(m.tetLabels);
  c.materials = std::move(m.materials);
  out.elementOrder = 2;
  for (size_t t = 0; t < c.tets.size(); ++t)
    for (size_t k = 0; k < 6; ++k) {
      const int32_t a = c.tets[t][size_t(kTet10Edges[k][0])],
                    b = c.tets[t][size_t(kTet10Edges[k][1])];
      const Vec3& p = m.points[size_t(mids[t][k])];
      const auto [it, added] = out.midEdgeNodes.emplace(tetEdgeKey(a, b), p);
      if (!added && it->second != p)
        return Result<MeshFile>(
            fail(ErrorCode::CorruptFile, path,
                 "two tetrahedra give the edge of nodes " + std::to_string(a + 1) + " and " +
                     std::to_string(b + 1) +
                     " different mid-edge nodes (not a conformal 10-node mesh).")
                .status());
    }
  return out;
}

}  // namespace

Result<TetMesh> readMesh(const std::string& path) {
  auto file = readMeshFile(path);
  if (!file) return file.status();
  return std::move(file.value().mesh);
}

Result<MeshFile> readMeshFile(const std::string& path) {
  using namespace meshio;
  using R = Result<MeshFile>;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    return R(fail(ErrorCode::FileNotFound, path, "the file does not exist.").status());
  if (std::filesystem::is_directory(path, ec))
    return R(fail(ErrorCode::UnreadableFile, path, "it is a folder, not a mesh file.").status());
  const std::string ext = fileExtension(path);
  std::vector<std::array<int32_t, 6>> mids;
  try {
    Result<TetMesh> m = Status(ErrorCode::Internal, "");
    if (ext == ".vtu")
      m = readVtu(path, &mids);
    else if (ext == ".vtk")
      m = readLegacyVtk(path, &mids);
    else if (ext == ".mesh")
      m = readMedit(path);
    else if (ext == ".msh")
      m = readMsh(path, &mids);
    else if (ext == ".inp")
      m = readInp(path, &mids);
    else
      return R(fail(ErrorCode::UnreadableFile, path,
                    "unsupported extension '" + ext +
                        "'; FEMesher reads .vtu, .vtk, .msh (4.1 ASCII), "
                        ".inp (as FEMesher writes it) and .mesh (Medit).")
                   .status());
    if (!m) return R(m.status());
    return cornerMesh(std::move(m).value(), mids, path);
  } catch (const Error& e) {
    return R(e.status());
  } catch (const std::exception& e) {
    return R(fail(ErrorCode::CorruptFile, path, e.what()).status());
  }
}

}  // namespace femesher
