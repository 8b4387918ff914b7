// SPDX-License-Identifier: GPL-3.0-or-later
// Medit (INRIA) ASCII (.mesh): writer and reader.
#include <femesher/Version.h>
#include <femesher/io/MeshFormats.h>

#include <array>
#include <fstream>

namespace femesher::meshio {

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

}  // namespace femesher::meshio
