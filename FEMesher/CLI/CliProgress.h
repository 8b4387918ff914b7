// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Progress display for the CLI: a bar on a terminal, Slicer's <filter-progress> protocol otherwise.
#include <femesher/RunContext.h>

#include <string>

namespace femesher::cli {

class CliProgress {
 public:
  enum class Mode { Bar, Slicer, Quiet };
  explicit CliProgress(Mode mode) : mode_(mode) {}
  static Mode detect(bool quiet);

  void start(const std::string& what);
  void update(const std::string& stage, double stageFraction, double total);
  void log(LogLevel level, const std::string& message);
  void finish(bool ok);

 private:
  Mode mode_;
  std::string stage_;
  int lastPermille_ = -1;
  bool barShown_ = false;
};

}  // namespace femesher::cli
