// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelMapFiles.h
/// Private to the label-map .cxx files of io/ (not part of the public API): the helpers reading
/// and writing label-map files share, and the checks of a file's header against its data that
/// must run before ITK reads it (ITK silently zero-fills data that is missing).

#include <femesher/Status.h>

#include <cstdint>
#include <string>

namespace itk {
class ExceptionObject;
}

namespace femesher::labelio {

/// `s` without leading and trailing blanks (spaces, tabs, CR, LF).
std::string trim(const std::string& s);

/// "'<path>'", how every label-map message names its file.
std::string quoted(const std::string& path);

/// ITK's description without its "ITK ERROR: NrrdImageIO(0x...): " prefix, on one line.
std::string itkMessage(const itk::ExceptionObject& e);

/// CorruptFile "'<path>' is damaged: <what>. Re-export the file ...".
Status corrupt(const std::string& path, const std::string& what);

/// `x` as the shortest text that reads back the same ("nan", "inf", "-0.5", "1e+300").
std::string number(double x);

/// CorruptFile for a header whose geometry is impossible: "'<path>' has an invalid header: its
/// <field> is <value> (<why>). Fix the header ... and check it with `femesher info`".
Status badGeometry(const std::string& path, const std::string& field, const std::string& value,
                   const std::string& why);

/// A MetaImage (.mha/.mhd) header that lies about its data: a CompressedDataSize that differs
/// from the bytes there, raw data shorter than the voxels described, a missing data file.
/// CorruptFile then; OK when the data is complete or the header too unusual to check (ITK
/// reports what it cannot read itself).
Status checkMetaImage(const std::string& path);

/// A NIfTI file (.nii, .nii.gz) whose data is shorter than its header says, or whose gzip stream
/// is cut or damaged: CorruptFile. Also a pixdim[1..3] that is not finite and > 0, and a qform or
/// sform (when its code is > 0) with an entry that is not finite or a singular sform: ITK's reader
/// would silently read a NaN or zero pixdim as 1 mm (badGeometry). OK for complete files and for
/// what is not NIfTI.
Status checkNifti(const std::string& path);

/// A NRRD (.nrrd, .nhdr, .seg.nrrd) whose data is not all there, checked from its header before
/// ITK allocates anything: raw data shorter than `sizes` x `type` (CorruptFile naming both byte
/// counts); gzip data that cannot hold that many bytes (deflate expands at most 1032:1, so a
/// memory bomb fails at once), that is cut off, damaged (zlib's CRC-32 and length checks of the
/// gzip trailer) or decodes to fewer bytes than the header says. OK for complete files and for
/// what it cannot check (ascii/hex/bzip2 data, multi-file data: ITK reports those itself).
/// First the geometry of the spatial axes (kind domain/space/time, or no kinds, and a direction
/// that is not "none"), which ITK either refuses with its own text or substitutes: `spacings`
/// finite and > 0, `space directions` finite, non-zero and independent, `space origin` finite
/// (badGeometry naming the field and its value).
Status checkNrrd(const std::string& path);

/// Whether this process can hold `bytesNeeded` bytes (the voxels as stored plus their int32
/// labels: what reading the label map needs at least): compared with the memory available
/// (MemAvailable of /proc/meminfo, else sysconf's free pages; lower when the address-space limit
/// RLIMIT_AS is lower). UnreadableFile naming both amounts, the dimensions and what to do.
Status checkMemory(const std::string& path, const int dims[3], uintmax_t voxels,
                   uintmax_t storedBytes, uintmax_t bytesNeeded);

/// Bytes this process can still allocate (see checkMemory); 0 when unknown.
uintmax_t availableMemory();

}  // namespace femesher::labelio
