// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/WorkingGrid.h>

#include <algorithm>

namespace femesher {

double WorkingGrid::minSpacing() const { return std::min({spacing[0], spacing[1], spacing[2]}); }

LabelVolume WorkingGrid::geometryIn(const LabelVolume& input) const {
  LabelVolume g;
  g.dims = dims;
  g.spacing = spacing;
  g.direction = input.direction;
  g.origin = input.indexToPhysical({double(offset[0]), double(offset[1]), double(offset[2])});
  g.sourcePath = input.sourcePath;
  return g;
}

}  // namespace femesher
