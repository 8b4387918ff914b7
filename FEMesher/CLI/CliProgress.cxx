// SPDX-License-Identifier: GPL-3.0-or-later
#include "CliProgress.h"

#include <femesher/StageTable.h>

#include <cstdio>
#include <cstdlib>
#include <unistd.h>

namespace femesher::cli {

std::string stageTitle(const std::string& key) {
  const StageInfo* info = findStage(key);
  return info ? info->title : key;
}

CliProgress::Mode CliProgress::detect(bool quiet, bool slicerInvocation) {
  if (quiet) return Mode::Quiet;
  if (::isatty(STDERR_FILENO)) return Mode::Bar;
  return slicerInvocation ? Mode::Slicer : Mode::Plain;
}

void CliProgress::start(const std::string& what) {
  if (mode_ == Mode::Slicer) {
    std::printf("<filter-start>\n<filter-name>FEMesher</filter-name>\n"
                "<filter-comment>%s</filter-comment>\n</filter-start>\n", what.c_str());
    std::fflush(stdout);
  }
}

void CliProgress::clearBar() {
  if (!barShown_) return;
  std::fprintf(stderr, "\r%-79s\r", "");  // wider than the bar line
  barShown_ = false;
}

void CliProgress::endStage() {
  if (stage_.empty() || (mode_ != Mode::Bar && mode_ != Mode::Plain)) return;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - stageStart_).count();
  clearBar();
  std::fprintf(stderr, "  %-30s %8.2f s\n", stageTitle(stage_).c_str(), seconds);
  std::fflush(stderr);
  stage_.clear();
}

void CliProgress::update(const std::string& stage, double stageFraction, double total) {
  if (mode_ == Mode::Quiet) return;
  const int permille = int(total * 1000);
  if (stage == stage_ && permille == lastPermille_) return;
  const bool newStage = stage != stage_;
  if (mode_ == Mode::Slicer) {
    if (newStage)
      std::printf("<filter-comment>%s</filter-comment>\n", stageTitle(stage).c_str());
    std::printf("<filter-progress>%.4f</filter-progress>\n", total);
    std::printf("<filter-stage-progress>%.4f</filter-stage-progress>\n", stageFraction);
    std::fflush(stdout);
  } else {
    if (newStage) {
      endStage();
      stageStart_ = std::chrono::steady_clock::now();
    }
    if (mode_ == Mode::Bar) {
      const int width = 30, filled = int(total * width + 0.5);
      std::string bar(size_t(filled), '#');
      bar.resize(width, '-');
      std::fprintf(stderr, "\r[%s] %5.1f%%  %-26s", bar.c_str(), total * 100,
                   stageTitle(stage).c_str());
      std::fflush(stderr);
      barShown_ = true;
    }
  }
  stage_ = stage;
  lastPermille_ = permille;
}

void CliProgress::log(LogLevel level, const std::string& message) {
  // Debug lines (per-iteration figures) only with FEMESHER_DEBUG set in the environment.
  static const bool showDebug = std::getenv("FEMESHER_DEBUG") != nullptr;
  if (level == LogLevel::Debug && !showDebug) return;
  if (mode_ == Mode::Quiet && level != LogLevel::Warning) return;
  clearBar();
  std::fprintf(stderr, "%s%s\n", level == LogLevel::Warning ? "warning: " : "", message.c_str());
}

void CliProgress::finish(bool ok) {
  if (mode_ == Mode::Slicer) {
    if (ok) std::printf("<filter-progress>1</filter-progress>\n");
    std::printf("<filter-end>\n<filter-name>FEMesher</filter-name>\n</filter-end>\n");
    std::fflush(stdout);
    return;
  }
  endStage();
  clearBar();
}

}  // namespace femesher::cli
