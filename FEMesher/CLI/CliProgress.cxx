// SPDX-License-Identifier: GPL-3.0-or-later
#include "CliProgress.h"

#include <cstdio>
#include <cstdlib>
#include <unistd.h>

namespace femesher::cli {

CliProgress::Mode CliProgress::detect(bool quiet) {
  if (quiet) return Mode::Quiet;
  return ::isatty(STDERR_FILENO) ? Mode::Bar : Mode::Slicer;
}

void CliProgress::start(const std::string& what) {
  if (mode_ == Mode::Slicer) {
    std::printf("<filter-start>\n<filter-name>FEMesher</filter-name>\n"
                "<filter-comment>%s</filter-comment>\n</filter-start>\n", what.c_str());
    std::fflush(stdout);
  }
}

void CliProgress::update(const std::string& stage, double stageFraction, double total) {
  if (mode_ == Mode::Quiet) return;
  const int permille = int(total * 1000);
  if (stage == stage_ && permille == lastPermille_) return;
  if (mode_ == Mode::Slicer) {
    if (stage != stage_)
      std::printf("<filter-comment>%s</filter-comment>\n", stage.c_str());
    std::printf("<filter-progress>%.4f</filter-progress>\n", total);
    std::printf("<filter-stage-progress>%.4f</filter-stage-progress>\n", stageFraction);
    std::fflush(stdout);
  } else {
    const int width = 30, filled = int(total * width + 0.5);
    std::string bar(size_t(filled), '#');
    bar.resize(width, '-');
    std::fprintf(stderr, "\r[%s] %5.1f%%  %-20s", bar.c_str(), total * 100, stage.c_str());
    std::fflush(stderr);
    barShown_ = true;
  }
  stage_ = stage;
  lastPermille_ = permille;
}

void CliProgress::log(LogLevel level, const std::string& message) {
  // Debug lines (per-iteration figures) only with FEMESHER_DEBUG set in the environment.
  static const bool showDebug = std::getenv("FEMESHER_DEBUG") != nullptr;
  if (level == LogLevel::Debug && !showDebug) return;
  if (mode_ == Mode::Quiet && level != LogLevel::Warning) return;
  if (barShown_) {
    std::fprintf(stderr, "\n");
    barShown_ = false;
  }
  std::fprintf(stderr, "%s%s\n", level == LogLevel::Warning ? "warning: " : "", message.c_str());
}

void CliProgress::finish(bool ok) {
  if (mode_ == Mode::Slicer) {
    if (ok) std::printf("<filter-progress>1</filter-progress>\n");
    std::printf("<filter-end>\n<filter-name>FEMesher</filter-name>\n</filter-end>\n");
    std::fflush(stdout);
  } else if (barShown_) {
    std::fprintf(stderr, "\n");
    barShown_ = false;
  }
}

}  // namespace femesher::cli
