// SPDX-License-Identifier: GPL-3.0-or-later
#include "CliCommon.h"

#include <femesher/io/LabelMapIO.h>
#include <femesher/io/LabelTable.h>

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

}  // namespace femesher::cli
