// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file AtomicFile.h
/// Atomic output: write to a temporary file in the destination folder, then rename over the
/// destination. A failed or canceled run never leaves a partial file. `OutputTransaction` does
/// this for every output of a run at once: nothing is renamed into place until all are written.

#include <femesher/Status.h>

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

/// Writes a temporary file: `writer(tmpPath)` must write the whole file at tmpPath.
using FileWriter = std::function<Status(const std::string& tmpPath)>;

/// The outputs of one run as one transaction. `stage` writes each to a temporary file in its
/// target folder (".<name>.tmp<pid>_<n><ext>", the real extension last since ITK and VTK choose
/// the format from it); `commit` renames them all into place only when every one was staged
/// without error. When a rename fails half way, the files already renamed are put back as they
/// were (an existing file is restored, a new one removed). The destructor removes every temporary
/// file not committed, so a failed or abandoned transaction touches no existing file.
class OutputTransaction {
 public:
  OutputTransaction() = default;
  ~OutputTransaction();
  OutputTransaction(const OutputTransaction&) = delete;
  OutputTransaction& operator=(const OutputTransaction&) = delete;

  /// Writes `path`'s content to a temporary file with `writer`. Errors (WriteFailed for I/O;
  /// femesher::Error and std::exception are converted) name `path`, never the temporary file; the
  /// temporary file is removed then. A writer reporting success without a file is WriteFailed.
  /// After an error the transaction is failed: `commit` refuses.
  Status stage(const std::string& path, const FileWriter& writer);

  /// Renames every staged file into place (all or none). WriteFailed when a stage failed or a
  /// rename fails.
  Status commit();

 private:
  struct Staged {
    std::string tmp, path;
  };
  std::vector<Staged> staged_;
  bool failed_ = false;
};

/// One output written atomically: an OutputTransaction of `path` alone.
Status writeAtomically(const std::string& path, const FileWriter& writer);

/// The outputs of one run must be distinct files: InvalidArgument naming both paths when two of
/// `paths` are the same file (compared as canonical paths: "a/../x.vtu" and "x.vtu", a symbolic
/// link and its target). Empty paths are skipped.
Status checkDistinctOutputs(const std::vector<std::string>& paths);

/// Lower-case extension including compound ones: ".vtu", ".nii.gz", ".seg.nrrd".
std::string fileExtension(const std::string& path);

}  // namespace femesher
