// SPDX-License-Identifier: GPL-3.0-or-later
// Abaqus / CalculiX input (.inp): model data only, C3D4 (or C3D10) per material, surfaces,
// materials; and its reader (nodes, elements, materials from the element sets).
#include <femesher/Version.h>
#include <femesher/io/MeshFormats.h>
#include <femesher/io/QuadraticTets.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <unordered_map>

namespace femesher::meshio {

namespace {

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

/// Abaqus C3D4 and C3D10 face numbering (1-based; the faces of a C3D10 are those of its corners): S1 = 1-2-3, S2 = 1-4-2, S3 = 2-4-3, S4 = 3-4-1.
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

/// Abaqus face number (S1..S4) of the face opposite local corner `opposite` (see abaqusFace).
int abaqusFaceOpposite(int opposite) {
  static const int S[4] = {3, 4, 2, 1};
  return S[opposite];
}

/// Penalty slope (MPa/mm) of a contact pair's linear pressure-overclosure: 50 x the softer
/// side's Young's modulus over the mean edge length h of the contact faces. The contact pressure
/// is bounded by the softer side (about its E times its strain), so the overclosure stays near
/// strain x h / 50, a small fraction of an element.
double contactSlope(const TetMesh& m, const ContactSurfacePair& c, const ExportOptions& o) {
  double edges = 0;
  size_t count = 0;
  for (const ElementFace& f : c.facesA) {
    const auto v = outwardFace(m, f);
    for (int k = 0; k < 3; ++k) {
      const Vec3 &a = m.points[size_t(v[size_t(k)])], &b = m.points[size_t(v[size_t((k + 1) % 3)])];
      edges += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                         (a[2] - b[2]) * (a[2] - b[2]));
      ++count;
    }
  }
  const double h = count ? edges / double(count) : 1.0;
  const double e = std::min(propsFor(o, c.labelA).youngsModulus, propsFor(o, c.labelB).youngsModulus);
  return 50.0 * e / (h > 0 ? h : 1.0);
}

/// Writes `ids` (already 1-based) comma separated, at most 16 per data line.
void writeIdLines(std::FILE* f, const std::vector<size_t>& ids) {
  for (size_t i = 0; i < ids.size(); ++i) {
    const bool last = i + 1 == ids.size() || (i + 1) % 16 == 0;
    std::fprintf(f, "%zu%s", ids[i], last ? "\n" : ", ");
  }
}

}  // namespace

Status writeInp(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const SolverDeckTables tables(m);
  const auto& [byLabel, tris, patches, elset] = tables;
  const bool quadratic = o.elementOrder == 2;
  const QuadraticTetMesh q =
      quadratic ? quadraticTets(m, o.midEdgeNodes.get()) : QuadraticTetMesh{};
  const std::vector<Vec3>& points = quadratic ? q.points : m.points;
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
                 "** NSET=BOUNDARY: nodes on the outer boundary; N_<elset>: nodes of a material;\n"
                 "** N_IF_<a>_<b>, N_OUTER_<a>: nodes of the surfaces below. Element-based surfaces:\n"
                 "**   IF_<a>_<b> interface between labels a < b (faces of a's elements),\n"
                 "**   OUTER_<a> outer boundary of label a (negative labels written N<|a|>).\n");
    if (!o.contacts.empty())
      std::fprintf(f,
                   "** Contact pairs (contact_pairs): the a|b interface is split into two coincident\n"
                   "**   surfaces with their own nodes: CONTACT_<a>_<b>_S (faces of a's elements, the\n"
                   "**   dependent side) and CONTACT_<a>_<b>_M (b's, the independent side), with a\n"
                   "**   *SURFACE INTERACTION SI_<a>_<b> (linear penalty) and a *CONTACT PAIR.\n");
    if (!o.nodeSets.empty())
      std::fprintf(f,
                   "** NSET BOX_XMIN..BOX_ZMAX: nodes on the faces of the scan's box (X, Y, Z = the\n"
                   "**   image's voxel axes i, j, k; MIN at the first voxel's outer edge).\n");
    if (quadratic)
      std::fprintf(f, "** C3D10: nodes after %zu are mid-edge nodes, %s.\n", q.cornerCount,
                   o.midEdgeNodes && !o.midEdgeNodes->empty()
                       ? "those of interface and boundary edges on the smooth interfaces"
                       : "at the straight edge midpoints");
    std::fprintf(f, "*NODE, NSET=ALLNODES\n");
    for (size_t i = 0; i < points.size(); ++i)
      std::fprintf(f, "%zu, %s, %s, %s\n", i + 1, inpReal(points[i][0]).c_str(),
                   inpReal(points[i][1]).c_str(), inpReal(points[i][2]).c_str());
    // Elements grouped by material; element id = 1-based index in the mesh (as in the .vtu).
    for (const auto& [l, tets] : byLabel) {
      std::fprintf(f, "*ELEMENT, TYPE=%s, ELSET=%s\n", quadratic ? "C3D10" : "C3D4",
                   elset.at(l).c_str());
      for (size_t t : tets) {
        if (!quadratic) {
          std::fprintf(f, "%zu, %d, %d, %d, %d\n", t + 1, m.tets[t][0] + 1, m.tets[t][1] + 1,
                       m.tets[t][2] + 1, m.tets[t][3] + 1);
          continue;
        }
        // C3D10: corners, then the midpoints of edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4 (q's order).
        std::fprintf(f, "%zu", t + 1);
        for (int32_t v : q.tets[t]) std::fprintf(f, ", %d", v + 1);
        std::fprintf(f, "\n");
      }
    }
    // Outer boundary nodes.
    std::set<int32_t> boundary;
    for (const auto& t : tris)
      if (t.labelB == kExteriorLabel) {
        boundary.insert(t.v.begin(), t.v.end());
        if (quadratic)
          for (int k = 0; k < 3; ++k) boundary.insert(q.midNode(t.v[size_t(k)], t.v[size_t((k + 1) % 3)]));
      }
    std::vector<size_t> ids;
    for (int32_t v : boundary) ids.push_back(size_t(v) + 1);
    std::fprintf(f, "*NSET, NSET=BOUNDARY\n");
    writeIdLines(f, ids);
    // Node sets where loads and fixations go: per material (N_<elset>) and per interface or outer
    // boundary patch (N_IF_<a>_<b>, N_OUTER_<a>), mid-edge nodes included for C3D10.
    auto writeNodeSet = [&](const std::string& name, const std::set<int32_t>& nodes) {
      std::vector<size_t> setIds;
      for (int32_t v : nodes) setIds.push_back(size_t(v) + 1);
      std::fprintf(f, "*NSET, NSET=%s\n", name.substr(0, 80).c_str());
      writeIdLines(f, setIds);
    };
    for (const auto& [l, tets] : byLabel) {
      std::set<int32_t> nodes;
      for (size_t t : tets) {
        if (quadratic) nodes.insert(q.tets[t].begin(), q.tets[t].end());
        else nodes.insert(m.tets[t].begin(), m.tets[t].end());
      }
      writeNodeSet("N_" + elset.at(l), nodes);
    }
    for (const auto& [key, list] : patches) {
      std::set<int32_t> nodes;
      for (size_t i : list) {
        const auto& t = tris[i];
        nodes.insert(t.v.begin(), t.v.end());
        if (quadratic)
          for (int k = 0; k < 3; ++k) nodes.insert(q.midNode(t.v[size_t(k)], t.v[size_t((k + 1) % 3)]));
      }
      writeNodeSet(key.second == kExteriorLabel
                       ? "N_OUTER_" + labelToken(key.first)
                       : "N_IF_" + labelToken(key.first) + "_" + labelToken(key.second),
                   nodes);
    }
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
    for (const auto& n : o.nodeSets) {
      std::vector<size_t> setIds;
      for (int32_t v : exportedNodeSet(m, n, quadratic ? &q : nullptr)) setIds.push_back(size_t(v) + 1);
      std::fprintf(f, "*NSET, NSET=%s\n", n.name.c_str());
      writeIdLines(f, setIds);
    }
    // Contact pairs: the two sides' element faces, the interaction, the pair (dependent first).
    for (const auto& c : o.contacts) {
      const std::string base = labelToken(c.labelA) + "_" + labelToken(c.labelB);
      for (const auto* faces : {&c.facesA, &c.facesB}) {
        std::fprintf(f, "*SURFACE, NAME=CONTACT_%s_%s, TYPE=ELEMENT\n", base.c_str(),
                     faces == &c.facesA ? "S" : "M");
        for (const ElementFace& face : *faces)
          std::fprintf(f, "%d, S%d\n", face.tet + 1, abaqusFaceOpposite(face.opposite));
      }
      std::fprintf(f, "*SURFACE INTERACTION, NAME=SI_%s\n", base.c_str());
      std::fprintf(f, "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n%s\n",
                   inpReal(contactSlope(m, c, o)).c_str());
      std::fprintf(f, "*CONTACT PAIR, INTERACTION=SI_%s, TYPE=SURFACE TO SURFACE\n", base.c_str());
      std::fprintf(f, "CONTACT_%s_S, CONTACT_%s_M\n", base.c_str(), base.c_str());
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

Result<TetMesh> readInp(const std::string& path, std::vector<std::array<int32_t, 6>>* midNodes) {
  std::ifstream in(path);
  if (!in) return fail(ErrorCode::UnreadableFile, path, "the file cannot be opened.");
  enum class Section { Other, Node, Element };
  Section section = Section::Other;
  int nodesPerElement = 0;
  int32_t label = 0;
  bool quadratic = false, sawKeyword = false;
  TetMesh m;
  std::unordered_map<long long, int32_t> nodeIndex;
  std::vector<std::array<long long, 10>> raw;
  std::map<int32_t, std::string> names;
  int32_t namedLabel = 0;
  const std::regex labelComment(R"(^\*\*   label (-?\d+) -> ELSET=)"),
      nameComment(R"(^\*\*     name '(.*)'$)");
  const std::regex elset(R"(ELSET\s*=\s*([MN])(\d+)_)", std::regex::icase);
  std::string line;
  size_t lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::smatch g;
    if (line.rfind("**", 0) == 0) {
      if (std::regex_search(line, g, labelComment))
        namedLabel = std::stoi(g[1]);
      else if (std::regex_search(line, g, nameComment))
        names[namedLabel] = g[1];
      continue;
    }
    const std::string where = "line " + std::to_string(lineNo);
    if (!line.empty() && line[0] == '*') {
      sawKeyword = true;
      std::string up = line;
      for (char& c : up) c = char(std::toupper(static_cast<unsigned char>(c)));
      section = Section::Other;
      if (up.rfind("*NODE", 0) == 0 && up.rfind("*NODE PRINT", 0) != 0 &&
          up.rfind("*NODE FILE", 0) != 0) {
        section = Section::Node;
      } else if (up.rfind("*ELEMENT", 0) == 0) {
        const bool c3d4 = up.find("TYPE=C3D4") != std::string::npos;
        const bool c3d10 = up.find("TYPE=C3D10") != std::string::npos;
        if (!c3d4 && !c3d10)
          return fail(ErrorCode::UnreadableFile, path,
                      where + ": only C3D4 and C3D10 elements are supported (" +
                          oneLine(line).substr(0, 80) + ").");
        if (c3d10 && !midNodes)
          return fail(ErrorCode::UnreadableFile, path,
                      where + ": 10-node tetrahedra are not supported here.");
        if (!std::regex_search(up, g, elset))
          return fail(
              ErrorCode::UnreadableFile, path,
              where +
                  ": the element set is not named M<label>_... as FEMesher writes it, so the "
                  "elements have no material.");
        label = int32_t(std::stol(g[2])) * (g[1] == "N" ? -1 : 1);
        nodesPerElement = c3d10 ? 10 : 4;
        quadratic |= c3d10;
        section = Section::Element;
      }
      continue;
    }
    if (section == Section::Other || line.find_first_not_of(" \t") == std::string::npos) continue;
    std::vector<double> f;
    for (const char* p = line.c_str(); *p;) {
      char* end = nullptr;
      const double x = std::strtod(p, &end);
      if (end == p) return fail(ErrorCode::CorruptFile, path, where + ": not a number list.");
      f.push_back(x);
      p = end;
      while (*p == ' ' || *p == '\t' || *p == ',') ++p;
    }
    if (section == Section::Node) {
      if (f.size() < 4)
        return fail(ErrorCode::CorruptFile, path, where + ": a node needs an id and x, y, z.");
      if (!nodeIndex.emplace((long long)f[0], int32_t(m.points.size())).second)
        return fail(ErrorCode::CorruptFile, path,
                    where + ": node " + std::to_string((long long)f[0]) + " is defined twice.");
      m.points.push_back({{f[1], f[2], f[3]}});
    } else {
      if (int(f.size()) != nodesPerElement + 1)
        return fail(ErrorCode::CorruptFile, path,
                    where + ": an element needs an id and " + std::to_string(nodesPerElement) +
                        " nodes on one line.");
      std::array<long long, 10> v;
      v.fill(-1);
      for (int k = 0; k < nodesPerElement; ++k) v[size_t(k)] = (long long)f[size_t(k) + 1];
      raw.push_back(v);
      m.tetLabels.push_back(label);
    }
  }
  if (!sawKeyword)
    return fail(ErrorCode::UnreadableFile, path,
                "it has no keyword lines (not an Abaqus input file).");
  for (const auto& v : raw) {
    std::array<int32_t, 10> t;
    t.fill(-1);
    for (size_t k = 0; k < 10; ++k) {
      if (v[k] < 0) continue;
      const auto it = nodeIndex.find(v[k]);
      if (it == nodeIndex.end())
        return fail(ErrorCode::CorruptFile, path,
                    "an element uses undefined node " + std::to_string(v[k]) + ".");
      t[k] = it->second;
    }
    m.tets.push_back({t[0], t[1], t[2], t[3]});
    if (quadratic) midNodes->push_back({t[4], t[5], t[6], t[7], t[8], t[9]});
  }
  return finishRead(std::move(m), path, names);
}

}  // namespace femesher::meshio
