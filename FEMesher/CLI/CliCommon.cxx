// SPDX-License-Identifier: GPL-3.0-or-later
#include "CliCommon.h"

#include <femesher/io/AtomicFile.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/LabelTable.h>

#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>

namespace femesher::cli {

int fail(const Status& s) {
  std::fprintf(stderr, "error [%s]: %s\n", errorCodeName(s.code()), s.message().c_str());
  return exitCodeFor(s.code());
}

std::string jsonText(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    if (static_cast<unsigned char>(c) < 0x20) o += ' ';
    else o += c;
  }
  return o;
}

Result<LabelVolume> readNamedLabelMap(const std::string& input, const std::string& labelNames) {
  auto volume = readLabelMap(input);
  if (!volume || labelNames.empty()) return volume;
  auto table = readLabelTable(labelNames);
  if (!table) return table.status();
  LabelVolume v = std::move(volume).value();
  if (Status s = applyLabelTable(v, table.value(), labelNames); !s) return s;
  return v;
}

namespace {

std::atomic<RunContext*> gRunning{nullptr};
std::atomic<bool> gReading{false};

void onSignal(int) {
  if (RunContext* ctx = gRunning.load()) ctx->cancel();
  if (gReading.load()) {
    static const char text[] = "error [canceled]: The run was canceled.\n";
    const ssize_t ignored = ::write(STDERR_FILENO, text, sizeof text - 1);
    (void)ignored;
    ::_exit(exitCodeFor(ErrorCode::Canceled));
  }
}

}  // namespace

void cancelOnSignal(RunContext* ctx) {
  gRunning = ctx;
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
}

ReadingScope::ReadingScope() { gReading = true; }
ReadingScope::~ReadingScope() { gReading = false; }

CancellableCommand::CancellableCommand() {
  cancelOnSignal(&ctx);
  setProcessCancelFlag(ctx.cancelToken().flag());
}

CancellableCommand::~CancellableCommand() {
  setProcessCancelFlag(nullptr);
  cancelOnSignal(nullptr);
}

}  // namespace femesher::cli
