// SPDX-License-Identifier: GPL-3.0-or-later
// ASCII STL (.stl): one solid per interface patch.
#include <femesher/io/MeshFormats.h>

#include <cmath>

namespace femesher::meshio {

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

}  // namespace femesher::meshio
