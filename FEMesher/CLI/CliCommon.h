// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Helpers every femesher subcommand uses: the error line and exit code, JSON text, named label maps.
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

}  // namespace femesher::cli
