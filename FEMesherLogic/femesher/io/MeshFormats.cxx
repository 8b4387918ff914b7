// SPDX-License-Identifier: GPL-3.0-or-later
// Helpers shared by the mesh formats (declared in MeshFormats.h).
#include <femesher/io/MeshFormats.h>

#include <cctype>
#include <cmath>
#include <cstring>
#include <set>

namespace femesher::meshio {

namespace {

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

}  // namespace

const ElasticProperties& propsFor(const ExportOptions& o, int32_t label) {
  auto it = o.materialProperties.find(label);
  return it != o.materialProperties.end() ? it->second : o.defaultMaterial;
}

std::string materialName(const TetMesh& m, int32_t label) {
  const Material* mat = findMaterial(m.materials, label);
  return mat && !mat->name.empty() ? mat->name : "label " + std::to_string(label);
}

std::string oneLine(const std::string& s, const char* drop) {
  std::string o;
  for (char c : s) {
    if (std::strchr(drop, c) && c != '\0') continue;
    o += static_cast<unsigned char>(c) < 0x20 ? ' ' : c;
  }
  return o;
}

std::string labelToken(int32_t l) {
  return l < 0 ? "N" + std::to_string(-int64_t(l)) : std::to_string(l);
}

std::vector<int32_t> meshLabels(const TetMesh& m) {
  std::set<int32_t> s(m.tetLabels.begin(), m.tetLabels.end());
  return {s.begin(), s.end()};
}

std::map<int32_t, std::vector<size_t>> tetsByLabel(const TetMesh& m) {
  std::map<int32_t, std::vector<size_t>> by;
  for (size_t t = 0; t < m.tets.size(); ++t) by[m.tetLabels[t]].push_back(t);
  return by;
}

std::map<PatchKey, std::vector<size_t>> patchesOf(const std::vector<InterfaceTriangle>& tris) {
  std::map<PatchKey, std::vector<size_t>> patches;
  for (size_t i = 0; i < tris.size(); ++i) patches[{tris[i].labelA, tris[i].labelB}].push_back(i);
  return patches;
}

std::string patchName(const PatchKey& k) {
  if (k.second == kExteriorLabel) return "boundary_" + std::to_string(k.first);
  return "interface_" + std::to_string(k.first) + "_" + std::to_string(k.second);
}

Status ioError(const std::string& path) {
  return {ErrorCode::WriteFailed,
          "Cannot write '" + path + "': the disk may be full or the folder not writable."};
}

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

std::map<int32_t, std::string> febioNames(const TetMesh& m) {
  std::map<int32_t, std::string> out;
  std::set<std::string> used = {"boundary", "nodes", "all_nodes"};
  for (int32_t l : meshLabels(m)) {
    std::string base;
    for (char c : materialName(m, l)) {
      const unsigned char u = static_cast<unsigned char>(c);
      if (u < 128 && std::isalnum(u)) base += c;
      else if (!base.empty() && base.back() != '_') base += '_';
    }
    if (base.size() > 48) base.resize(48);
    while (!base.empty() && base.back() == '_') base.pop_back();
    if (base.empty()) base = "label_" + labelToken(l);
    else if (std::isdigit(static_cast<unsigned char>(base[0]))) base = "m_" + base;
    std::string n = base;
    if (used.count(n)) n = base + "_" + labelToken(l);
    for (int k = 2; used.count(n); ++k) n = base + "_" + labelToken(l) + "_" + std::to_string(k);
    used.insert(n);
    out[l] = n;
  }
  return out;
}

std::map<int32_t, std::string> uniqueMaterialNames(const TetMesh& m, const char* drop) {
  std::map<int32_t, std::string> out;
  std::map<std::string, int> count;
  for (int32_t l : meshLabels(m)) ++count[out[l] = oneLine(materialName(m, l), drop)];
  for (auto& [l, name] : out)
    if (count[name] > 1 || name.empty()) name += " (label " + std::to_string(l) + ")";
  return out;
}

Result<TetMesh> fail(ErrorCode code, const std::string& path, const std::string& what) {
  return Result<TetMesh>(code, "Cannot read mesh '" + path + "': " + what);
}

Result<TetMesh> finishRead(TetMesh m, const std::string& path, const std::map<int32_t, std::string>& names,
                           const std::map<int32_t, std::array<double, 3>>& colors) {
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

std::vector<int32_t> exportedNodeSet(const TetMesh& m, const NamedNodeSet& set,
                                     const QuadraticTetMesh* q) {
  std::set<int32_t> nodes(set.nodes.begin(), set.nodes.end());
  if (q) {
    std::vector<char> in(m.points.size(), 0);
    for (int32_t v : set.nodes) in[size_t(v)] = 1;
    for (const auto& t : m.tets)
      for (const auto& e : kTet10Edges)
        if (in[size_t(t[size_t(e[0])])] && in[size_t(t[size_t(e[1])])])
          nodes.insert(q->midNode(t[size_t(e[0])], t[size_t(e[1])]));
  }
  return {nodes.begin(), nodes.end()};
}

std::array<int32_t, 3> outwardFace(const TetMesh& m, const ElementFace& f) {
  const auto& t = m.tets[size_t(f.tet)];
  std::array<int32_t, 3> v{};
  for (int i = 0, n = 0; i < 4; ++i)
    if (i != f.opposite) v[size_t(n++)] = t[size_t(i)];
  const Vec3 &a = m.points[size_t(v[0])], &b = m.points[size_t(v[1])], &c = m.points[size_t(v[2])];
  const Vec3& o = m.points[size_t(t[size_t(f.opposite)])];
  const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const Vec3 nrm{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  const double toOpposite =
      nrm[0] * (o[0] - a[0]) + nrm[1] * (o[1] - a[1]) + nrm[2] * (o[2] - a[2]);
  if (toOpposite > 0) std::swap(v[1], v[2]);
  return v;
}

}  // namespace femesher::meshio
