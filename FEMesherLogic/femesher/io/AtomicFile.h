// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file AtomicFile.h
/// Atomic output: write to a temporary file in the destination folder, then rename over the
/// destination. A failed or canceled run never leaves a partial file. `OutputTransaction` does
/// this for every output of a run at once: nothing is renamed into place until all are written.

#include <femesher/Status.h>

#include <atomic>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

/// Writes a temporary file: `writer(tmpPath)` must write the whole file at tmpPath.
using FileWriter = std::function<Status(const std::string& tmpPath)>;

/// The outputs of one run as one transaction. `stage` writes each to a temporary file in its
/// target folder (".<name>.femesher-tmp-<pid>-<n><ext>", see `temporaryFileOwner`; the real
/// extension last since ITK and VTK choose the format from it); `commit` renames them all into
/// place only when every one was staged without error. When a rename fails half way, the files
/// already renamed are put back as they were (an existing file is restored, a new one removed).
/// The destructor removes every temporary file not committed, so a failed or abandoned
/// transaction touches no existing file. With a cancel flag (`setCancelFlag`), a cancel request
/// is honoured up to the last rename: `stage` writes nothing once it is set, and `commit` checks
/// it before every rename and rolls back the renames already done (Canceled).
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
  /// rename fails, Canceled when the cancel flag is set before the last rename.
  Status commit();

  /// A flag (e.g. RunContext's cancel token) that cancels the transaction when set; may be null.
  void setCancelFlag(const std::atomic<bool>* flag) { cancel_ = flag; }

 private:
  struct Staged {
    std::string tmp, path;
  };
  bool canceled() const { return cancel_ && cancel_->load(); }
  std::vector<Staged> staged_;
  bool failed_ = false;
  const std::atomic<bool>* cancel_ = nullptr;
};

/// The process id that owns `fileName` (a name without folder) when it is a temporary or backup
/// file of an OutputTransaction: ".<name>.femesher-tmp-<pid>-<n>[<ext>]" or
/// ".<name>.femesher-bak-<pid>-<n>[<ext>]", <ext> at most two parts of letters and digits
/// (".nii.gz"); 0 for every other name.
long temporaryFileOwner(const std::string& fileName);

/// Removes the temporary and backup files (temporaryFileOwner) of processes that no longer exist
/// from the folders of `outputs` (not their subfolders): what a run killed by SIGKILL or a power
/// cut left. Files of a live process (this one included) and every other name are left alone; a
/// process counts as live when kill(pid, 0) succeeds or is refused for permission (so the folder
/// must not be shared with runs on another machine or in another PID namespace). Returns the
/// paths removed.
std::vector<std::string> removeStaleTemporaries(const std::vector<std::string>& outputs);

/// One output written atomically: an OutputTransaction of `path` alone, cancelled by the
/// process's cancel flag when one is set (setProcessCancelFlag).
Status writeAtomically(const std::string& path, const FileWriter& writer);

/// The cancel flag every writeAtomically of this process honours (a command-line run sets its
/// signal-driven flag so that a single-output command stops before its rename); null = none.
void setProcessCancelFlag(const std::atomic<bool>* flag);

/// The outputs of one run must be distinct files: InvalidArgument naming both paths when two of
/// `paths` are the same file (compared as canonical paths: "a/../x.vtu" and "x.vtu", a symbolic
/// link and its target). Empty paths are skipped.
Status checkDistinctOutputs(const std::vector<std::string>& paths);

/// Lower-case extension including compound ones: ".vtu", ".nii.gz", ".seg.nrrd".
std::string fileExtension(const std::string& path);

}  // namespace femesher
