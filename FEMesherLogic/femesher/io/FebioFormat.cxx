// SPDX-License-Identifier: GPL-3.0-or-later
// FEBio 2.5 model (.feb): nodes, a tet4 domain and a neo-Hookean material per label, surfaces.
#include <femesher/Version.h>
#include <femesher/io/MeshFormats.h>

namespace femesher::meshio {

namespace {

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

}  // namespace

Status writeFeb(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const SolverDeckTables tables(m);
  const auto& [byLabel, tris, patches, elset] = tables;
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

}  // namespace femesher::meshio
