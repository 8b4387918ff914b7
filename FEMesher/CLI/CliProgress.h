// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Progress display for the CLI. Every mode but Slicer and Quiet prints one line per finished
// stage (its human title and seconds); a terminal also gets a bar that redraws in place.
#include <femesher/RunContext.h>

#include <chrono>
#include <string>

namespace femesher::cli {

class CliProgress {
 public:
  /// Bar: stderr is a terminal (stage lines and a bar redrawn with '\r').
  /// Plain: stderr is a file or pipe outside Slicer (stage lines only, no '\r', no XML).
  /// Slicer: Slicer's <filter-progress> protocol on stdout (only when Slicer runs the module).
  /// Quiet: warnings only.
  enum class Mode { Bar, Plain, Slicer, Quiet };
  explicit CliProgress(Mode mode) : mode_(mode) {}
  /// `slicerInvocation`: called the way Slicer calls CLI modules (no subcommand); Slicer mode
  /// needs it and a stderr that is not a terminal (Slicer reads the module through pipes).
  static Mode detect(bool quiet, bool slicerInvocation);
  Mode mode() const { return mode_; }

  void start(const std::string& what);
  void update(const std::string& stage, double stageFraction, double total);
  void log(LogLevel level, const std::string& message);
  void finish(bool ok);

 private:
  void endStage();  ///< the stage line of the current stage (Bar and Plain)
  void clearBar();

  Mode mode_;
  std::string stage_;
  std::chrono::steady_clock::time_point stageStart_;
  int lastPermille_ = -1;
  bool barShown_ = false;
};

/// The human title of a stage key ("ParticleSystem" -> "Particles settling"); other names are
/// returned unchanged.
std::string stageTitle(const std::string& key);

}  // namespace femesher::cli
