// SPDX-License-Identifier: GPL-3.0-or-later
// FEBio input file, format 4.0 (.feb): Module, Control, Material, Mesh (Nodes, one Elements
// domain per material, NodeSets, Surfaces) and MeshDomains. The structure follows FEBio's user
// manual for format 4.0 (sections "Free Format Overview", "Control Section", "Material Section",
// "Mesh Section", "MeshDomains Section") and what FEBio's 4.0 reader requires (material ids
// 1..N in order with unique names, node and element ids increasing, Elements named, a
// SolidDomain per Elements naming a material by name). With element_order 2: tet10 elements
// (corners, then the midpoints of edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4, the order of FEBio's
// FETet10 shape functions), tri6 surface faces (corners, then edges 1-2, 2-3, 3-1) and NodeSets
// holding the mid-edge nodes. Contact pairs (ExportOptions::contacts): per pair two Surfaces, a
// SurfacePair (<primary>, <secondary>, as FEBio's 4.0 mesh reader reads them) and a
// "sliding-elastic" contact in a Contact section, with parameters of the manual's sliding-elastic
// table (penalty with auto_penalty, frictionless, one pass).
#include <femesher/Version.h>
#include <femesher/io/MeshFormats.h>
#include <femesher/io/QuadraticTets.h>

#include <set>

namespace femesher::meshio {

namespace {

/// Text that may stand inside an XML comment: printable ASCII, no "--".
std::string commentText(const std::string& s) {
  std::string o;
  for (char c : oneLine(s)) {
    const unsigned char u = static_cast<unsigned char>(c);
    const char x = u >= 0x80 ? '?' : c;
    if (x == '-' && !o.empty() && o.back() == '-') continue;
    o += x;
  }
  return o;
}

/// Writes `ids` (1-based) comma separated, 16 per line, as the value of a NodeSet.
void writeIdList(std::FILE* f, const std::set<int32_t>& nodes) {
  size_t i = 0;
  for (int32_t v : nodes) {
    const bool last = ++i == nodes.size();
    std::fprintf(f, "%s%d%s", i % 16 == 1 ? "\t\t\t" : "", v + 1,
                 last ? "\n" : (i % 16 == 0 ? ",\n" : ","));
  }
}

}  // namespace

Status writeFeb(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const SolverDeckTables tables(m);
  const auto& byLabel = tables.byLabel;
  const auto& tris = tables.tris;
  const auto& patches = tables.patches;
  const auto names = febioNames(m);
  const bool quadratic = o.elementOrder == 2;
  const QuadraticTetMesh q =
      quadratic ? quadraticTets(m, o.midEdgeNodes.get()) : QuadraticTetMesh{};
  const std::vector<Vec3>& points = quadratic ? q.points : m.points;
  // The nodes of tet t and of interface triangle i (mid-edge nodes too with order 2).
  auto insertTetNodes = [&](std::set<int32_t>& nodes, size_t t) {
    if (quadratic) nodes.insert(q.tets[t].begin(), q.tets[t].end());
    else nodes.insert(m.tets[t].begin(), m.tets[t].end());
  };
  auto triNodes = [&](size_t i) {
    const auto& v = tris[i].v;
    std::vector<int32_t> n(v.begin(), v.end());
    if (quadratic)
      for (int k = 0; k < 3; ++k) n.push_back(q.midNode(v[size_t(k)], v[size_t((k + 1) % 3)]));
    return n;
  };
  auto surfaceName = [&](const PatchKey& k) {
    return names.at(k.first) + "__" +
           (k.second == kExteriorLabel ? "boundary" : names.at(k.second));
  };
  return writeText(path, [&](std::FILE* f) {
    std::fprintf(f, "<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>\n");
    std::fprintf(
        f,
        "<!-- FEMesher %s%s\n"
        "     Units: LPS mm, N, MPa, tonne/mm^3 (s). Materials: neo-Hookean from E and nu.\n"
        "     Element ids are unique, 1..N over all domains. Surfaces <a>__<b>: the interface of\n"
        "     materials a and b, faces oriented outward from a; <a>__boundary: a's outer "
        "boundary,\n"
        "     faces oriented outward. NodeSets nodes__<a>, nodes__<a>__<b>, nodes__<a>__boundary:\n"
        "     the nodes of a material, an interface, an outer boundary. BOX_XMIN..BOX_ZMAX: nodes\n"
        "     on the faces of the scan's box (X, Y, Z = the image's voxel axes i, j, k). Split\n"
        "     contact pairs: Surfaces contact__<a>__<b>__<a> / __<b> (each side's faces, outward\n"
        "     from its own elements), SurfacePair contact__<a>__<b> (primary a) and a\n"
        "     sliding-elastic contact. Add Boundary and Loads sections (and edit Control) for an\n"
        "     analysis.\n",
        FEMESHER_VERSION, o.provenance.empty() ? "" : (": " + commentText(o.provenance)).c_str());
    for (const auto& [l, n] : names)
      std::fprintf(f, "     label %d '%s' -> material and domain %s\n", l,
                   commentText(materialName(m, l)).c_str(), n.c_str());
    std::fprintf(f, "-->\n<febio_spec version=\"4.0\">\n\t<Module type=\"solid\"/>\n");
    // A static step; the solver parameters are the manual's Control Section example.
    std::fprintf(f,
                 "\t<Control>\n\t\t<analysis>STATIC</analysis>\n\t\t<time_steps>10</time_steps>\n"
                 "\t\t<step_size>0.1</step_size>\n\t\t<solver type=\"solid\">\n"
                 "\t\t\t<max_refs>25</max_refs>\n\t\t\t<diverge_reform>1</diverge_reform>\n"
                 "\t\t\t<reform_each_time_step>1</reform_each_time_step>\n"
                 "\t\t\t<dtol>0.001</dtol>\n\t\t\t<etol>0.01</etol>\n\t\t\t<rtol>0</rtol>\n"
                 "\t\t\t<lstol>0.9</lstol>\n\t\t\t<min_residual>1e-20</min_residual>\n"
                 "\t\t\t<qn_method type=\"BFGS\">\n\t\t\t\t<max_ups>10</max_ups>\n"
                 "\t\t\t</qn_method>\n\t\t</solver>\n\t</Control>\n");
    std::fprintf(f, "\t<Material>\n");
    int matId = 0;
    for (const auto& [l, tets] : byLabel) {
      const ElasticProperties& p = propsFor(o, l);
      std::fprintf(f, "\t\t<material id=\"%d\" name=\"%s\" type=\"neo-Hookean\">\n", ++matId,
                   names.at(l).c_str());
      std::fprintf(f, "\t\t\t<density>%.17g</density>\n\t\t\t<E>%.17g</E>\n\t\t\t<v>%.17g</v>\n",
                   p.density, p.youngsModulus, p.poissonRatio);
      std::fprintf(f, "\t\t</material>\n");
    }
    std::fprintf(f, "\t</Material>\n\t<Mesh>\n\t\t<Nodes name=\"all_nodes\">\n");
    for (size_t i = 0; i < points.size(); ++i)
      std::fprintf(f, "\t\t\t<node id=\"%zu\">%.17g,%.17g,%.17g</node>\n", i + 1, points[i][0],
                   points[i][1], points[i][2]);
    std::fprintf(f, "\t\t</Nodes>\n");
    // Element ids run on over the domains (FEBio looks elements up by id).
    size_t eid = 0;
    for (const auto& [l, tets] : byLabel) {
      std::fprintf(f, "\t\t<Elements type=\"%s\" name=\"%s\">\n", quadratic ? "tet10" : "tet4",
                   names.at(l).c_str());
      for (size_t t : tets) {
        std::fprintf(f, "\t\t\t<elem id=\"%zu\">", ++eid);
        if (quadratic)
          for (size_t k = 0; k < 10; ++k) std::fprintf(f, "%s%d", k ? "," : "", q.tets[t][k] + 1);
        else
          for (size_t k = 0; k < 4; ++k) std::fprintf(f, "%s%d", k ? "," : "", m.tets[t][k] + 1);
        std::fprintf(f, "</elem>\n");
      }
      std::fprintf(f, "\t\t</Elements>\n");
    }
    for (const auto& [l, tets] : byLabel) {
      std::set<int32_t> nodes;
      for (size_t t : tets) insertTetNodes(nodes, t);
      std::fprintf(f, "\t\t<NodeSet name=\"nodes__%s\">\n", names.at(l).c_str());
      writeIdList(f, nodes);
      std::fprintf(f, "\t\t</NodeSet>\n");
    }
    for (const auto& [key, list] : patches) {
      std::set<int32_t> nodes;
      for (size_t i : list)
        for (int32_t v : triNodes(i)) nodes.insert(v);
      std::fprintf(f, "\t\t<NodeSet name=\"nodes__%s\">\n", surfaceName(key).c_str());
      writeIdList(f, nodes);
      std::fprintf(f, "\t\t</NodeSet>\n");
    }
    for (const auto& n : o.nodeSets) {
      const auto ids = exportedNodeSet(m, n, quadratic ? &q : nullptr);
      std::fprintf(f, "\t\t<NodeSet name=\"%s\">\n", n.name.c_str());
      writeIdList(f, std::set<int32_t>(ids.begin(), ids.end()));
      std::fprintf(f, "\t\t</NodeSet>\n");
    }
    // Faces in the order extractInterfaces gives: outward from labelA's tet.
    for (const auto& [key, list] : patches) {
      std::fprintf(f, "\t\t<Surface name=\"%s\">\n", surfaceName(key).c_str());
      size_t fid = 0;
      const char* type = quadratic ? "tri6" : "tri3";
      for (size_t i : list) {
        std::fprintf(f, "\t\t\t<%s id=\"%zu\">", type, ++fid);
        const auto n = triNodes(i);
        for (size_t k = 0; k < n.size(); ++k) std::fprintf(f, "%s%d", k ? "," : "", n[k] + 1);
        std::fprintf(f, "</%s>\n", type);
      }
      std::fprintf(f, "\t\t</Surface>\n");
    }
    auto pairName = [&](const ContactSurfacePair& c) {
      return "contact__" + names.at(c.labelA) + "__" + names.at(c.labelB);
    };
    for (const auto& c : o.contacts)
      for (const auto* faces : {&c.facesA, &c.facesB}) {
        const int32_t side = faces == &c.facesA ? c.labelA : c.labelB;
        std::fprintf(f, "\t\t<Surface name=\"%s__%s\">\n", pairName(c).c_str(),
                     names.at(side).c_str());
        size_t fid = 0;
        const char* type = quadratic ? "tri6" : "tri3";
        for (const ElementFace& face : *faces) {
          const auto v = outwardFace(m, face);
          std::vector<int32_t> n(v.begin(), v.end());
          if (quadratic)
            for (int k = 0; k < 3; ++k) n.push_back(q.midNode(v[size_t(k)], v[size_t((k + 1) % 3)]));
          std::fprintf(f, "\t\t\t<%s id=\"%zu\">", type, ++fid);
          for (size_t k = 0; k < n.size(); ++k) std::fprintf(f, "%s%d", k ? "," : "", n[k] + 1);
          std::fprintf(f, "</%s>\n", type);
        }
        std::fprintf(f, "\t\t</Surface>\n");
      }
    for (const auto& c : o.contacts)
      std::fprintf(f,
                   "\t\t<SurfacePair name=\"%s\">\n\t\t\t<primary>%s__%s</primary>\n"
                   "\t\t\t<secondary>%s__%s</secondary>\n\t\t</SurfacePair>\n",
                   pairName(c).c_str(), pairName(c).c_str(), names.at(c.labelA).c_str(),
                   pairName(c).c_str(), names.at(c.labelB).c_str());
    std::fprintf(f, "\t</Mesh>\n\t<MeshDomains>\n");
    for (const auto& [l, tets] : byLabel)
      std::fprintf(f, "\t\t<SolidDomain name=\"%s\" mat=\"%s\"/>\n", names.at(l).c_str(),
                   names.at(l).c_str());
    std::fprintf(f, "\t</MeshDomains>\n");
    if (!o.contacts.empty()) {
      std::fprintf(f, "\t<Contact>\n");
      for (const auto& c : o.contacts)
        std::fprintf(f,
                     "\t\t<contact type=\"sliding-elastic\" name=\"%s\" surface_pair=\"%s\">\n"
                     "\t\t\t<penalty>1</penalty>\n\t\t\t<auto_penalty>1</auto_penalty>\n"
                     "\t\t\t<two_pass>0</two_pass>\n\t\t\t<search_tol>0.01</search_tol>\n"
                     "\t\t\t<symmetric_stiffness>0</symmetric_stiffness>\n"
                     "\t\t\t<fric_coeff>0</fric_coeff>\n\t\t</contact>\n",
                     pairName(c).c_str(), pairName(c).c_str());
      std::fprintf(f, "\t</Contact>\n");
    }
    std::fprintf(f, "</febio_spec>\n");
  });
}

}  // namespace femesher::meshio
