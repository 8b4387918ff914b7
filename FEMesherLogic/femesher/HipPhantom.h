// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file HipPhantom.h
/// A clinical-size test volume, written by this project: the planning CT of both hips, as a label
/// map of 512 x 512 x 400 voxels at 0.7 x 0.7 x 1.0 mm (358 x 358 x 400 mm) with 10 labels. The
/// patient's right hip (x < 0, LPS) has a total hip replacement, the left hip is native:
///
///   1 pelvis cortical bone (a 2 mm shell)     6 cartilage (3 mm between the native femoral head
///   2 pelvis trabecular bone                    and the acetabulum)
///   3 femur cortical bone (6 mm on the shaft,  7 implant: stem in the right femoral canal, neck,
///     2 mm at the metaphysis and neck)           ball and acetabular cup (one body)
///   4 femur trabecular bone                    8 muscle (all soft tissue inside the fat layer)
///   5 marrow (the canals of both shafts)       9 fat (a 14 mm subcutaneous layer)
///  10 subchondral bone plate: the thin cortical shell of the native femoral head under the
///     cartilage, 1-2 voxels thick at every size (voxels whose farthest 26-neighbour lies outside
///     the head), between trabecular bone and cartilage.
///
/// Shapes: ellipsoids, capsules, tapered capsules, spheres and elliptic cylinders combined by
/// smooth minima, evaluated per voxel centre (in parallel), so the result is deterministic and
/// independent of the thread count. The pelvis is one ring (ilia, sacrum, pubic and ischial rami
/// around both obturator foramina); the femurs are cut by the field of view at the bottom, the
/// body at top and bottom, with background around the body. Nested shells: fat around muscle
/// around bone; cortical around trabecular around marrow; the implant touches cortical and
/// trabecular bone and marrow of the femur and both pelvic bone labels (the cup).
///
/// `scale` < 1 makes the same anatomy on fewer, larger voxels: dims round(512 s) x round(512 s)
/// x round(400 s), spacing 0.7 * 512 / nx etc. (exactly 0.7 x 0.7 x 1.0 at scale 1).

#include <femesher/Types.h>

namespace femesher {

struct HipPhantomOptions {
  double scale = 1.0;  ///< (0.05, 2]; 1 = 512 x 512 x 400 voxels
  int threads = 0;     ///< 0 = all cores (the labels do not depend on it)
};

/// The label values of the hip phantom (see the file comment).
enum HipLabel : int32_t {
  kHipPelvisCortical = 1,
  kHipPelvisTrabecular = 2,
  kHipFemurCortical = 3,
  kHipFemurTrabecular = 4,
  kHipMarrow = 5,
  kHipCartilage = 6,
  kHipImplant = 7,
  kHipMuscle = 8,
  kHipFat = 9,
  kHipSubchondralPlate = 10,
};

/// The phantom's header only (dims, spacing, origin; no labels, no materials): what
/// makeHipPhantom makes, without computing a voxel. Throws Error(InvalidArgument) for a scale
/// outside (0.05, 2].
LabelVolume hipPhantomHeader(const HipPhantomOptions& options = {});

/// The phantom. Throws Error(InvalidArgument) for a scale outside (0.05, 2].
LabelVolume makeHipPhantom(const HipPhantomOptions& options = {});

}  // namespace femesher
