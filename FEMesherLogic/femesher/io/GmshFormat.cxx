// SPDX-License-Identifier: GPL-3.0-or-later
// Gmsh MSH 4.1 ASCII (.msh): writer and reader.
#include <femesher/io/MeshFormats.h>
#include <femesher/io/QuadraticTets.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>

namespace femesher::meshio {

namespace {

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

}  // namespace

Status writeMsh(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const bool quadratic = o.elementOrder == 2;
  const QuadraticTetMesh q =
      quadratic ? quadraticTets(m, o.midEdgeNodes.get()) : QuadraticTetMesh{};
  const std::vector<Vec3>& points = quadratic ? q.points : m.points;
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
    const auto names = uniqueMaterialNames(m, "\"");
    for (int32_t l : labels)
      std::fprintf(f, "3 %d \"%s\"\n", tags.volumePhysical.at(l), names.at(l).c_str());
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
    // With element_order 2 the mid-edge nodes follow the corners.
    const size_t np = points.size();
    std::fprintf(f, "$Nodes\n1 %zu 1 %zu\n3 %d 0 %zu\n", np, np, volTag.at(labels.front()), np);
    for (size_t i = 0; i < np; ++i) std::fprintf(f, "%zu\n", i + 1);
    for (size_t i = 0; i < np; ++i)
      std::fprintf(f, "%.17g %.17g %.17g\n", points[i][0], points[i][1], points[i][2]);
    std::fprintf(f, "$EndNodes\n");
    const size_t ne = tris.size() + m.tets.size();
    std::fprintf(f, "$Elements\n%zu %zu 1 %zu\n", patches.size() + labels.size(), ne, ne);
    size_t id = 1;
    for (const auto& [key, list] : patches) {
      // Type 2 (3-node triangle) or 9 (6-node: corners, then edges 0-1, 1-2, 2-0).
      std::fprintf(f, "2 %d %d %zu\n", surfTag.at(key), quadratic ? 9 : 2, list.size());
      for (size_t i : list) {
        const auto& v = tris[i].v;
        std::fprintf(f, "%zu %d %d %d", id++, v[0] + 1, v[1] + 1, v[2] + 1);
        if (quadratic)
          std::fprintf(f, " %d %d %d", q.midNode(v[0], v[1]) + 1, q.midNode(v[1], v[2]) + 1,
                       q.midNode(v[2], v[0]) + 1);
        std::fprintf(f, "\n");
      }
    }
    for (int32_t l : labels) {
      const auto& list = byLabel.at(l);
      // Type 4 (4-node tet) or 11 (10-node tet in Gmsh's node order, kGmshTet10Order).
      std::fprintf(f, "3 %d %d %zu\n", volTag.at(l), quadratic ? 11 : 4, list.size());
      for (size_t t : list) {
        std::fprintf(f, "%zu", id++);
        if (quadratic)
          for (int k : kGmshTet10Order) std::fprintf(f, " %d", q.tets[t][size_t(k)] + 1);
        else
          for (int32_t v : m.tets[t]) std::fprintf(f, " %d", v + 1);
        std::fprintf(f, "\n");
      }
    }
    std::fprintf(f, "$EndElements\n");
  });
}

Result<TetMesh> readMsh(const std::string& path, std::vector<std::array<int32_t, 6>>* midNodes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(ErrorCode::UnreadableFile, path, "the file cannot be opened.");
  Tokens tok(in, path);
  TetMesh m;
  std::map<int, int> volumePhysical;        // volume entity tag -> first physical tag
  std::map<int, std::string> physNames;     // dim-3 physical tag -> name
  std::map<int, int32_t> physToLabel;       // from $FEMesherLabels
  std::unordered_map<long long, int32_t> nodeIndex;
  std::vector<std::pair<std::array<long long, 10>, int>> rawTets;  // node tags, volume entity
  bool quadratic = false;  // 10-node tets (type 11) in the file
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
        if (dim == 3 && type != 4 && !(type == 11 && midNodes))
          return fail(ErrorCode::UnreadableFile, path,
                      "it has volume elements that are not linear" +
                          std::string(midNodes ? " or 10-node" : "") + " tetrahedra (Gmsh type " +
                          std::to_string(type) + ").");
        quadratic |= type == 11;
        for (long long i = 0; i < n; ++i) {
          tok.get<long long>("$Elements");
          std::array<long long, 10> v{};
          v.fill(-1);
          for (int k = 0; k < nn; ++k) {
            const long long x = tok.get<long long>("$Elements");
            // Gmsh's tet10 puts edge (2,3)'s node before edge (1,3)'s: back to kTet10Edges order.
            if (type == 4 || type == 11) v[size_t(type == 11 ? kGmshTet10Order[size_t(k)] : k)] = x;
          }
          if (type == 4 || type == 11) rawTets.push_back({v, tag});
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
    std::array<int32_t, 10> t;
    t.fill(-1);
    for (size_t k = 0; k < 10; ++k) {
      if (v[k] < 0) continue;
      auto it = nodeIndex.find(v[k]);
      if (it == nodeIndex.end())
        return fail(ErrorCode::CorruptFile, path,
                    "a tetrahedron uses undefined node " + std::to_string(v[k]) + ".");
      t[k] = it->second;
    }
    m.tets.push_back({t[0], t[1], t[2], t[3]});
    if (quadratic) midNodes->push_back({t[4], t[5], t[6], t[7], t[8], t[9]});
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

}  // namespace femesher::meshio
