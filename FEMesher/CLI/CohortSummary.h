// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The cohort summary of a batch output folder: summary.csv, summary.json and summary.html (one
// self-contained page: a sortable table and inline SVG plots), one row per case, read from each
// case's run report (report.json) and batch record (batch-case.json).
#include <femesher/Status.h>

#include <string>
#include <vector>

namespace femesher::cli {

/// What the batch knows of a case besides its report.
struct CaseRecord {
  std::string id;
  std::string dir;            ///< the case's output folder
  std::string input;          ///< the label map
  std::string status;         ///< "ok", "failed", "canceled", "not_run"
  std::string run;            ///< "meshed" (this run), "up_to_date" (resumed), "not_run"
  int exitCode = -1;          ///< femesher mesh's exit code; -1 when it did not run
  double wallSeconds = -1;    ///< wall seconds of the child (the run that made the outputs)
  std::string error;          ///< the last lines of the child's stderr when it failed
};

/// File names inside a case folder.
inline const char* kCaseReport = "report.json";
inline const char* kCaseLog = "log.txt";
inline const char* kCaseRecord = "batch-case.json";

/// The records of every case folder under `outDir` (for `batch --summarise-only`, e.g. after a
/// Snakemake run): from batch-case.json when there is one, else from report.json (exit 0, the
/// report's seconds), else failed with the end of log.txt.
std::vector<CaseRecord> scanCaseFolders(const std::string& outDir);

/// The last `lines` non-empty lines of a text file ("" when unreadable).
std::string lastLines(const std::string& path, int lines);

/// What a failed case's log says: of its last 5 lines, those from the last "error" line on (the
/// stage lines before it left out), or all 5 when none is an error line.
std::string errorOf(const std::string& logPath);

/// Writes summary.csv, summary.json and summary.html into `outDir` (each atomically).
Status writeCohortSummary(const std::string& outDir, const std::vector<CaseRecord>& cases);

}  // namespace femesher::cli
