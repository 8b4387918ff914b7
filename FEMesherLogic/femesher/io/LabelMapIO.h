// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelMapIO.h
/// Reading and writing label maps with ITK: NRRD/NHDR, NIfTI (.nii, .nii.gz), MetaImage
/// (.mha/.mhd) and Slicer segmentations (.seg.nrrd). Geometry (origin, anisotropic spacing,
/// oblique or left-handed direction) is kept exactly, in LPS.
///
/// Errors (never a crash, never a partial output):
///  - FileNotFound: the path does not exist.
///  - UnreadableFile: no reader for the format, permission denied, not an image.
///  - CorruptFile: truncated data, or a header that lies about its data (e.g. a MetaImage
///    CompressedDataSize that does not match the data file: ITK would silently zero-fill).
///  - NotALabelMap: 2-D image, multi-component pixels (other than .seg.nrrd layers), or a float
///    image whose values are not all integers (a CT, not labels).
///  - EmptyLabelMap: only background (0).
///  - TooManyLabels: more than 65,535 distinct labels.
///  - OverlappingSegments: a .seg.nrrd whose segments overlap (several layers).
/// Every message names the file, the problem and what to do about it. The checks of the geometry
/// and of the voxel values are those of LabelValidation.h, shared with the other label-map sources.

#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/io/LabelMapSummary.h>  // summarizeLabelMap (femesher info)
#include <femesher/io/LabelValidation.h>  // the checks readLabelMap applies

#include <string>
#include <vector>

namespace femesher {

/// Read a label map. Materials get names/colours from a .seg.nrrd header, else defaults.
///
/// Any integer voxel type is accepted (8 to 64 bits, values within int32); float/double only when
/// every value is an integer. A 4-D image whose extra axes have size 1 is read as 3-D.
/// Slicer .seg.nrrd: a 3-D image (one layer) or a 4-D image with the layer axis first. The
/// material id of a segment is its LabelValue; when several layers reuse the same LabelValues
/// (Slicer numbers each layer from 1) the segments are numbered 1, 2, ... in header order instead.
/// Layers are merged when no voxel is set in two of them. Plain NRRD files carrying the same
/// Segment<N>_ keys (FEMesher writes them) get their names and colours too.
/// Before ITK reads it, a MetaImage header is checked against its data file (CompressedDataSize,
/// raw byte count) and a NIfTI file against its header's data size (ITK zero-fills both).
Result<LabelVolume> readLabelMap(const std::string& path);

/// Write a label map (format from the extension: .nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd),
/// atomically, with the volume's geometry. Labels are stored as the smallest integer type that
/// holds them (uint8, uint16, else int32), compressed (NRRD: gzip). The material table is stored
/// under Slicer's Segment<N>_ keys where the format keeps key/value pairs (NRRD, MetaImage).
/// A detached header (.nhdr, .mhd) gets its data file next to it under the same stem.
Status writeLabelMap(const LabelVolume& volume, const std::string& path);

/// Write a float scalar volume with the geometry of `geometry` (its labels are ignored), e.g. a
/// sizing field in mm. `values` has geometry.voxelCount() entries, x fastest.
Status writeScalarVolume(const LabelVolume& geometry, const std::vector<float>& values,
                         const std::string& path);

}  // namespace femesher
