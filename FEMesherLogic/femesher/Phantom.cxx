// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Phantom.h>

#include <cmath>

namespace femesher {

LabelVolume makePhantom(const PhantomOptions& o) {
  LabelVolume v;
  const double h = o.voxelSize > 0 ? o.voxelSize : 1.0;
  v.dims = {int(std::lround(64 / h)), int(std::lround(64 / h)), int(std::lround(96 / h))};
  v.spacing = {h, h, h};
  v.origin = o.origin;
  v.labels.assign(v.voxelCount(), 0);
  const double cx = 32, cy = 32;           // shaft axis (mm, in the volume's frame)
  const double headZ = 74, headR = 14;     // femoral head
  for (int k = 0; k < v.dims[2]; ++k)
    for (int j = 0; j < v.dims[1]; ++j)
      for (int i = 0; i < v.dims[0]; ++i) {
        const double x = (i + 0.5) * h, y = (j + 0.5) * h, z = (k + 0.5) * h;
        const double rAxis = std::hypot(x - cx, y - cy);
        const double rHead = std::sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - headZ) * (z - headZ));
        const bool shaft = rAxis < 12 && z > 6 && z < 66;
        const bool head = rHead < headR;
        const bool innerShaft = rAxis < 9 && z > 9 && z < 66;
        const bool innerHead = rHead < headR - 2.5;
        int label = 0;
        if (shaft || head) {
          label = 1;  // cortical
          if (innerShaft || innerHead) label = (innerShaft && z < 35) ? 3 : 2;
        } else if (rHead < headR + 2.5 && z > headZ + 4) {
          label = 4;  // cartilage cap
        }
        // Tapered stem: 2.5 mm radius at its tip in the marrow canal, 4 mm where it leaves the head.
        const bool stem = z > 20 && z < 92 && rAxis < 2.5 + 1.5 * (z - 20) / 72;
        const bool screw = std::hypot(y - cy, z - 35) < 2.5 && x > 14 && x < 50;
        if (stem || screw) label = 5;
        v.labels[v.index(i, j, k)] = label;
      }
  v.materials = {{1, "cortical bone", {0.95, 0.92, 0.80}},
                 {2, "trabecular bone", {0.85, 0.62, 0.40}},
                 {3, "marrow", {0.78, 0.25, 0.25}},
                 {4, "cartilage", {0.35, 0.65, 0.92}},
                 {5, "implant", {0.55, 0.50, 0.88}}};
  v.sourcePath = "phantom";
  return v;
}

}  // namespace femesher
