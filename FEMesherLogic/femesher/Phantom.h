// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Phantom.h
/// The built-in test volume, written by this project: a stylised proximal femur with an implant.
/// Labels: 1 cortical bone (a 2.5-3 mm shell), 2 trabecular bone, 3 marrow (the canal of the
/// shaft, below z = 35 mm), 4 cartilage (a 2.5 mm cap on the femoral head), 5 implant (a stem
/// along the axis, tapered from 2.5 mm radius at its tip in the marrow canal (z = 20 mm) to 4 mm
/// where it leaves through the head and cartilage, and a transverse screw through the shaft at
/// z = 35 mm). The screw meets cortical bone, marrow and trabecular bone on one line: quadruple
/// points; stem, head and cartilage give triple lines. 64 x 64 x 96 mm, background 0 around with
/// a margin of >= 4 voxels; identity direction, origin (-32, -32, 10) mm. Deterministic.

#include <femesher/Types.h>

namespace femesher {

struct PhantomOptions {
  double voxelSize = 1.0;               ///< mm, isotropic
  Vec3 origin{{-32.0, -32.0, 10.0}};    ///< LPS mm of voxel (0,0,0)
};

LabelVolume makePhantom(const PhantomOptions& options = {});

}  // namespace femesher
