// SPDX-License-Identifier: GPL-3.0-or-later
// Colour tables naming labels: Slicer .ctbl/.txt and .csv, ITK-SNAP label descriptions.
#include <femesher/io/LabelMapFiles.h>
#include <femesher/io/LabelTable.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace femesher {

namespace {

using labelio::trim;

Status badLine(const std::string& path, int line, const std::string& what) {
  return {ErrorCode::CorruptFile,
          labelio::quoted(path) + " line " + std::to_string(line) + ": " + what +
              ". A colour table has one entry per line: 'label name R G B A' (3D Slicer .ctbl), "
              "a CSV with LabelValue,Name columns (3D Slicer .csv) or 'label R G B A VIS MSH "
              "\"name\"' (ITK-SNAP); fix or remove that line."};
}

bool parseInt(const std::string& t, long long& out) {
  if (t.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtoll(t.c_str(), &end, 10);
  return errno == 0 && *end == '\0' && out >= INT32_MIN && out <= INT32_MAX;
}

bool parseReal(const std::string& t, double& out) {
  if (t.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtod(t.c_str(), &end);
  return errno == 0 && *end == '\0';
}

/// Sets `e.color` from R, G, B text (0..255); false when one is not such a number.
bool parseColor(const std::string& r, const std::string& g, const std::string& b,
                LabelTableEntry& e) {
  const std::string* c[3] = {&r, &g, &b};
  for (int k = 0; k < 3; ++k) {
    double x = 0;
    if (!parseReal(*c[k], x) || x < 0 || x > 255) return false;
    e.color[size_t(k)] = x / 255.0;
  }
  e.hasColor = true;
  return true;
}

/// Splits a CSV line at commas outside '"' quotes; false for an unterminated quote.
bool splitCsv(const std::string& line, std::vector<std::string>& out) {
  out.assign(1, std::string());
  bool inQuotes = false;
  for (char c : line) {
    if (c == '"')
      inQuotes = !inQuotes;
    else if (c == ',' && !inQuotes)
      out.emplace_back();
    else
      out.back() += c;
  }
  for (auto& v : out) v = trim(v);
  return !inQuotes;
}

/// A Slicer .ctbl line ("label name R G B A") or an ITK-SNAP line (`label R G B A VIS MSH "name"`).
Status parseTextLine(const std::string& path, int n, const std::string& line, LabelTableEntry& e) {
  e.line = n;
  const auto quote = line.find('"');
  std::istringstream in(line.substr(0, quote));
  std::vector<std::string> tok;
  for (std::string t; in >> t;) tok.push_back(t);
  long long label = 0;
  if (tok.empty() || !parseInt(tok[0], label))
    return badLine(path, n, "'" + (tok.empty() ? line : tok[0]) + "' is not an integer label");
  e.label = int32_t(label);
  if (quote != std::string::npos) {  // ITK-SNAP
    const auto close = line.find('"', quote + 1);
    if (close == std::string::npos) return badLine(path, n, "the name's closing quote is missing");
    e.name = trim(line.substr(quote + 1, close - quote - 1));
    if (tok.size() >= 4 && !parseColor(tok[1], tok[2], tok[3], e))
      return badLine(path, n, "the colour R G B must be numbers from 0 to 255");
  } else {  // Slicer
    if (tok.size() < 2) return badLine(path, n, "the label has no name");
    e.name = tok[1];
    if (tok.size() >= 5 && !parseColor(tok[2], tok[3], tok[4], e))
      return badLine(path, n, "the colour R G B must be numbers from 0 to 255");
  }
  if (e.name.empty()) return badLine(path, n, "the label's name is empty");
  return Status::ok();
}

}  // namespace

Result<std::vector<LabelTableEntry>> readLabelTable(const std::string& path) {
  using R = Result<std::vector<LabelTableEntry>>;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    return R(ErrorCode::FileNotFound,
             "Colour table " + labelio::quoted(path) +
                 " does not exist. Check the path given to --label-names.");
  if (std::filesystem::is_directory(path, ec))
    return R(ErrorCode::UnreadableFile,
             "Colour table " + labelio::quoted(path) + " is a folder, not a file.");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    return R(ErrorCode::UnreadableFile, "Cannot open colour table " + labelio::quoted(path) + ".");
  std::vector<LabelTableEntry> entries;
  std::map<int32_t, int> seen;      // label -> line
  std::vector<std::string> header;  // CSV columns, once a CSV header is seen
  int n = 0;
  for (std::string raw; std::getline(in, raw);) {
    ++n;
    const std::string line = trim(raw);
    if (line.empty() || line[0] == '#') continue;
    LabelTableEntry e;
    if (header.empty() && line.find("LabelValue") != std::string::npos &&
        line.find(',') != std::string::npos) {
      if (!splitCsv(line, header)) return R(badLine(path, n, "a quote is not closed"));
      continue;
    }
    if (!header.empty()) {
      std::vector<std::string> v;
      if (!splitCsv(line, v)) return R(badLine(path, n, "a quote is not closed"));
      std::map<std::string, std::string> col;
      for (size_t k = 0; k < header.size() && k < v.size(); ++k) col[header[k]] = v[k];
      long long label = 0;
      if (!parseInt(col["LabelValue"], label))
        return R(badLine(path, n, "LabelValue '" + col["LabelValue"] + "' is not an integer"));
      e.label = int32_t(label);
      e.line = n;
      e.name = col["Name"];
      if (e.name.empty()) continue;  // Slicer's CSV allows entries without a name: nothing to use
      if (col.count("Color_R") && col.count("Color_G") && col.count("Color_B") &&
          !parseColor(col["Color_R"], col["Color_G"], col["Color_B"], e))
        return R(badLine(path, n, "Color_R, Color_G, Color_B must be numbers from 0 to 255"));
    } else if (Status s = parseTextLine(path, n, line, e); !s) {
      return R(s);
    }
    if (auto it = seen.find(e.label); it != seen.end())
      return R(badLine(path, n,
                       "label " + std::to_string(e.label) + " is given again (first on line " +
                           std::to_string(it->second) + ")"));
    seen[e.label] = n;
    entries.push_back(std::move(e));
  }
  if (entries.empty())
    return R(ErrorCode::UnreadableFile, "Colour table " + labelio::quoted(path) +
                                            " names no label: it has no line 'label name R G B A' "
                                            "(3D Slicer), no CSV with LabelValue and Name columns "
                                            "and no ITK-SNAP line 'label R G B A "
                                            "VIS MSH \"name\"'. Give a colour table file.");
  return entries;
}

Status applyLabelTable(LabelVolume& volume, const std::vector<LabelTableEntry>& table,
                       const std::string& tablePath) {
  size_t used = 0;
  for (Material& m : volume.materials)
    for (const auto& e : table)
      if (e.label == m.id) {
        m.name = e.name;
        if (e.hasColor) m.color = e.color;
        ++used;
        break;
      }
  if (used > 0) return Status::ok();
  auto list = [](const std::set<int32_t>& s) {
    std::string t;
    size_t k = 0;
    for (int32_t l : s) {
      if (++k > 30) return t + ", ...";
      t += (t.empty() ? "" : ", ") + std::to_string(l);
    }
    return t;
  };
  std::set<int32_t> mine, theirs;
  for (const auto& m : volume.materials) mine.insert(m.id);
  for (const auto& e : table) theirs.insert(e.label);
  const std::string map =
      volume.sourcePath.empty() ? "the label map" : labelio::quoted(volume.sourcePath);
  return {ErrorCode::InvalidArgument, "Colour table " + labelio::quoted(tablePath) +
                                          " names none of the labels of " + map + ": it has " +
                                          list(theirs) + "; the label map has " +
                                          (mine.empty() ? std::string("none") : list(mine)) +
                                          ". Give the colour table made for this label map."};
}

}  // namespace femesher
