// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Helpers every femesher subcommand uses: the error line and exit code, JSON text, named label
// maps, and how Ctrl-C / SIGTERM cancel a command.
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/Types.h>

#include <string>

namespace femesher::cli {

/// Prints "error [<code name>]: <message>" on stderr and returns the exit code of `s`.
int fail(const Status& s);

/// `s` as the inside of a JSON string (names come from files and users: quotes, backslashes).
std::string jsonText(const std::string& s);

/// Reads a label map and, with `labelNames`, names its materials from that colour table.
Result<LabelVolume> readNamedLabelMap(const std::string& input, const std::string& labelNames);

/// SIGINT/SIGTERM from the first byte read to the last rename: a signal sets `ctx`'s cancel flag
/// (which the stages poll and the output transactions check before every write and rename), and
/// inside a ReadingScope ends the process at once with the canceled message and exit 12
/// (async-signal-safe: write and _exit). Installs the handlers; null: no run to cancel.
void cancelOnSignal(RunContext* ctx);

/// While it lives, nothing is written yet (the input is read, or a command that writes only at
/// its end computes): a signal ends the process at once (cancelOnSignal).
struct ReadingScope {
  ReadingScope();
  ~ReadingScope();
  ReadingScope(const ReadingScope&) = delete;
  ReadingScope& operator=(const ReadingScope&) = delete;
};

/// Ctrl-C / SIGTERM for a command that reads and computes before it writes one output (phantom,
/// quality, sizing, medial-axis): while it lives, a signal cancels its atomic writes before their
/// rename (writeAtomically: Canceled, exit 12); inside a ReadingScope the process ends at once.
struct CancellableCommand {
  CancellableCommand();
  ~CancellableCommand();
  CancellableCommand(const CancellableCommand&) = delete;
  CancellableCommand& operator=(const CancellableCommand&) = delete;
  RunContext ctx;
};

}  // namespace femesher::cli
