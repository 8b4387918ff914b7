// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file AtomicFile.h
/// Atomic output: write to a temporary file in the destination folder, then rename over the
/// destination. A failed or canceled run never leaves a partial file.

#include <femesher/Status.h>

#include <functional>
#include <string>

namespace femesher {

/// Calls `writer(tmpPath)`, which must write the whole file at tmpPath and return a Status.
/// On success renames tmpPath to `path`; on failure (or exception) removes tmpPath and returns
/// the error (WriteFailed for I/O problems). Exceptions of type femesher::Error are converted.
Status writeAtomically(const std::string& path,
                       const std::function<Status(const std::string& tmpPath)>& writer);

/// Lower-case extension including compound ones: ".vtu", ".nii.gz", ".seg.nrrd".
std::string fileExtension(const std::string& path);

}  // namespace femesher
