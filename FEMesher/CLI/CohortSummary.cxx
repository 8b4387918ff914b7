// SPDX-License-Identifier: GPL-3.0-or-later
#include "CohortSummary.h"

#include <femesher/Version.h>
#include <femesher/io/AtomicFile.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

namespace femesher::cli {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

/// Labels of at least this many voxels make the lowest Dice of a case (as the judge of real
/// volumes and issue 12's fidelity bound count them).
constexpr double kDiceVoxels = 1000;


constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// One row of the summary: the batch's record and what the case's report says.
struct Row {
  CaseRecord c;
  std::string status;  ///< c.status, or the report's ("ok", "poor_elements") when it succeeded
  long long tets = -1;
  double worst = kNaN;    ///< worst (smallest) dihedral angle, degrees
  double below10 = kNaN;  ///< percent of tets whose smallest dihedral angle is below 10 degrees
  double minDice = kNaN;
  std::string minDiceLabel;
  std::vector<std::pair<std::string, double>> dice;  ///< label id -> volume Dice
  std::vector<std::string> missing;                  ///< labels of the map not in the mesh
  std::vector<std::string> warnings;
};

std::string fmt(double v, const char* f) {
  if (std::isnan(v)) return "";
  char s[64];
  std::snprintf(s, sizeof s, f, v);
  return s;
}

json readJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) return json();
  try {
    return json::parse(in);
  } catch (const std::exception&) {
    return json();
  }
}

double number(const json& j, std::initializer_list<const char*> keys) {
  const json* p = &j;
  for (const char* k : keys) {
    if (!p->is_object() || !p->contains(k)) return kNaN;
    p = &(*p)[k];
  }
  return p->is_number() ? p->get<double>() : kNaN;
}

Row makeRow(const CaseRecord& c) {
  Row r;
  r.c = c;
  r.status = c.status;
  if (c.status != "ok") return r;
  const json rep = readJson((fs::path(c.dir) / kCaseReport).string());
  if (!rep.is_object()) {
    r.status = "failed";
    if (r.c.error.empty()) r.c.error = "no readable report.json";
    return r;
  }
  if (rep.contains("status") && rep["status"].is_string()) r.status = rep["status"];
  r.tets = (long long)number(rep, {"quality", "all", "tets"});
  r.worst = number(rep, {"quality", "all", "min_dihedral", "min"});
  if (std::isnan(r.worst)) r.worst = number(rep, {"mesh_check", "worst_min_dihedral"});
  const double below = number(rep, {"quality", "min_dihedral_below_10deg"});
  if (r.tets > 0 && !std::isnan(below)) r.below10 = 100.0 * below / double(r.tets);
  std::set<long long> listed;  // labels already named as missing
  if (rep.contains("input")) {
    const json& in = rep["input"];
    std::set<long long> excluded;
    if (in.contains("excluded_labels") && in["excluded_labels"].is_array())
      for (const auto& e : in["excluded_labels"])
        if (e.is_number()) excluded.insert(e.get<long long>());
    std::set<long long> dropped;
    if (in.contains("dropped_labels"))
      for (const auto& d : in["dropped_labels"])
        if (d.is_number()) dropped.insert(d.get<long long>());
    for (const long long d : dropped) {
      r.missing.push_back(std::to_string(d) + " (below min_voxels)");
      listed.insert(d);
    }
    if (in.contains("labels"))
      for (const auto& l : in["labels"]) {
        const long long id = l.value("id", 0LL);
        if (!l.value("in_mesh", true) && !excluded.count(id) && !dropped.count(id)) {
          r.missing.push_back(std::to_string(id) + " (not meshed)");
          listed.insert(id);
        }
      }
  }
  // Dice of every label of the map; the lowest over the labels in the mesh of at least
  // kDiceVoxels voxels, or over all of them when none is that large (a label of a few dozen
  // voxels has a low Dice by its size alone and would hide the outliers that matter; the Dice
  // per label still lists it). A label named missing above has Dice 0 by construction and is
  // reported as missing instead.
  if (rep.contains("fidelity") && rep["fidelity"].contains("materials")) {
    double lowestSmall = kNaN;
    std::string lowestSmallLabel;
    for (const auto& m : rep["fidelity"]["materials"]) {
      const long long id = m.value("label", 0LL);
      const std::string label = std::to_string(id);
      const double d = m.value("dice", kNaN);
      r.dice.emplace_back(label, d);
      if (listed.count(id)) continue;
      if (m.value("tets", 0) == 0) {
        r.missing.push_back(label + " (no tets)");
        continue;
      }
      if (std::isnan(d)) continue;
      if (m.value("voxels", 0.0) >= kDiceVoxels) {
        if (std::isnan(r.minDice) || d < r.minDice) r.minDice = d, r.minDiceLabel = label;
      } else if (std::isnan(lowestSmall) || d < lowestSmall) {
        lowestSmall = d, lowestSmallLabel = label;
      }
    }
    if (std::isnan(r.minDice)) r.minDice = lowestSmall, r.minDiceLabel = lowestSmallLabel;
  }
  if (rep.contains("warnings"))
    for (const auto& w : rep["warnings"])
      if (w.is_string()) r.warnings.push_back(w);
  return r;
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string o = "\"";
  for (char ch : s) o += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return o + "\"";
}

std::string joined(const std::vector<std::string>& v, const std::string& sep) {
  std::string o;
  for (const auto& s : v) o += (o.empty() ? "" : sep) + s;
  return o;
}

std::string diceText(const Row& r) {
  std::vector<std::string> parts;
  for (const auto& [l, d] : r.dice) parts.push_back(l + "=" + fmt(d, "%.4f"));
  return joined(parts, ";");
}

std::string oneLine(std::string s) {
  for (auto& ch : s)
    if (ch == '\n' || ch == '\r') ch = ' ';
  return s;
}

std::string csvText(const std::vector<Row>& rows) {
  std::string o =
      "case,status,exit_code,run,wall_s,tets,worst_dihedral_deg,below_10deg_percent,min_dice,"
      "min_dice_label,dice,missing_labels,n_warnings,warnings,error,input\n";
  for (const auto& r : rows) {
    const std::vector<std::string> f = {
        r.c.id, r.status, r.c.exitCode < 0 ? "" : std::to_string(r.c.exitCode), r.c.run,
        fmt(r.c.wallSeconds < 0 ? kNaN : r.c.wallSeconds, "%.2f"),
        r.tets < 0 ? "" : std::to_string(r.tets), fmt(r.worst, "%.3f"), fmt(r.below10, "%.4f"),
        fmt(r.minDice, "%.4f"), r.minDiceLabel, diceText(r), joined(r.missing, ";"),
        std::to_string(r.warnings.size()), oneLine(joined(r.warnings, " | ")),
        oneLine(r.c.error), r.c.input};
    std::vector<std::string> q;
    for (const auto& x : f) q.push_back(csvField(x));
    o += joined(q, ",") + "\n";
  }
  return o;
}

json nullable(double v) { return std::isnan(v) ? json() : json(v); }

std::string jsonText(const std::vector<Row>& rows, const std::string& when) {
  json cases = json::array();
  for (const auto& r : rows) {
    json dice = json::object();
    for (const auto& [l, d] : r.dice) dice[l] = nullable(d);
    cases.push_back({{"case", r.c.id},
                     {"input", r.c.input},
                     {"status", r.status},
                     {"exit_code", r.c.exitCode < 0 ? json() : json(r.c.exitCode)},
                     {"run", r.c.run},
                     {"wall_seconds", r.c.wallSeconds < 0 ? json() : json(r.c.wallSeconds)},
                     {"tets", r.tets < 0 ? json() : json(r.tets)},
                     {"worst_dihedral_deg", nullable(r.worst)},
                     {"below_10deg_percent", nullable(r.below10)},
                     {"min_dice", nullable(r.minDice)},
                     {"min_dice_label", r.minDiceLabel},
                     {"dice", dice},
                     {"missing_labels", r.missing},
                     {"warnings", r.warnings},
                     {"error", r.c.error}});
  }
  return json({{"femesher_version", FEMESHER_VERSION}, {"written", when}, {"cases", cases}})
      .dump(1);
}

std::string html(const std::string& s) {
  std::string o;
  for (char ch : s) {
    switch (ch) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      default: o += ch;
    }
  }
  return o;
}

const char* kBad = "#d62728";
const char* kFair = "#ff9f1c";
const char* kGood = "#2ca02c";

/// Tets (x) against wall seconds (y), both on log10 axes with decade ticks.
std::string scatterSvg(const std::vector<Row>& rows) {
  std::vector<const Row*> pts;
  for (const auto& r : rows)
    if (r.tets > 0 && r.c.wallSeconds > 0) pts.push_back(&r);
  const double W = 420, H = 300, L = 58, R = 14, T = 28, B = 42;
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
    << "' role='img'><text x='" << W / 2 << "' y='16' class='ttl'>Tets vs wall seconds</text>";
  if (pts.empty()) return s.str() + "<text x='60' y='140'>no meshed case</text></svg>";
  double x0 = 1e300, x1 = 0, y0 = 1e300, y1 = 0;
  for (const Row* r : pts) {
    x0 = std::min(x0, std::log10(double(r->tets)));
    x1 = std::max(x1, std::log10(double(r->tets)));
    y0 = std::min(y0, std::log10(r->c.wallSeconds));
    y1 = std::max(y1, std::log10(r->c.wallSeconds));
  }
  x0 = std::floor(x0), y0 = std::floor(y0), x1 = std::max(std::ceil(x1), x0 + 1),
  y1 = std::max(std::ceil(y1), y0 + 1);
  auto X = [&](double v) { return L + (std::log10(v) - x0) / (x1 - x0) * (W - L - R); };
  auto Y = [&](double v) { return H - B - (std::log10(v) - y0) / (y1 - y0) * (H - T - B); };
  s << "<rect x='" << L << "' y='" << T << "' width='" << W - L - R << "' height='" << H - T - B
    << "' class='frame'/>";
  for (double e = x0; e <= x1; ++e) {
    const double x = X(std::pow(10, e));
    s << "<line x1='" << x << "' x2='" << x << "' y1='" << T << "' y2='" << H - B
      << "' class='grid'/><text x='" << x << "' y='" << H - B + 14 << "' class='tick'>1e"
      << int(e) << "</text>";
  }
  for (double e = y0; e <= y1; ++e) {
    const double y = Y(std::pow(10, e));
    s << "<line x1='" << L << "' x2='" << W - R << "' y1='" << y << "' y2='" << y
      << "' class='grid'/><text x='" << L - 4 << "' y='" << y + 4 << "' class='tick' "
      << "text-anchor='end'>" << fmt(std::pow(10, e), "%g") << " s</text>";
  }
  s << "<text x='" << (L + W - R) / 2 << "' y='" << H - 6 << "' class='axis'>tets</text>";
  // Names beside the points, each where it overlaps no name placed before (right or left, above
  // or below its point); a name with no free place is left out (the point's tooltip has it).
  struct Box {
    double x0, y0, x1, y1;
  };
  std::vector<Box> placed;
  for (const Row* r : pts) placed.push_back({X(double(r->tets)) - 4, Y(r->c.wallSeconds) - 4,
                                             X(double(r->tets)) + 4, Y(r->c.wallSeconds) + 4});
  for (const Row* r : pts) {
    const double x = X(double(r->tets)), y = Y(r->c.wallSeconds);
    const char* colour = r->status == "ok" ? kGood : kFair;
    s << "<circle cx='" << x << "' cy='" << y << "' r='4' fill='" << colour << "'><title>"
      << html(r->c.id) << ": " << r->tets << " tets, " << fmt(r->c.wallSeconds, "%.1f")
      << " s</title></circle>";
    const double w = 5.6 * double(r->c.id.size()), h = 10;
    for (const auto& [right, above] : {std::pair{true, true}, {true, false}, {false, true},
                                      {false, false}}) {
      const Box b = {right ? x + 6 : x - 6 - w, above ? y - 5 - h : y + 5,
                     right ? x + 6 + w : x - 6, above ? y - 5 : y + 5 + h};
      if (b.x0 < L || b.x1 > W - R || b.y0 < T || b.y1 > H - B) continue;
      if (std::any_of(placed.begin(), placed.end(), [&](const Box& o) {
            return b.x0 < o.x1 && o.x0 < b.x1 && b.y0 < o.y1 && o.y0 < b.y1;
          }))
        continue;
      placed.push_back(b);
      s << "<text x='" << b.x0 << "' y='" << b.y1 - 2 << "' class='pt'>" << html(r->c.id)
        << "</text>";
      break;
    }
  }
  return s.str() + "</svg>";
}

/// One horizontal bar per case: value(row) on [lo, hi], a dashed reference line at `ref`,
/// coloured by colour(value); failed cases are named with no bar.
template <class Value, class Colour>
std::string barsSvg(const std::vector<Row>& rows, const std::string& title, double lo, double hi,
                    double step, double ref, const char* unit, const char* valueFormat,
                    Value value, Colour colour) {
  const double W = 420, L = 130, R = 44, T = 28, rowH = 16, B = 22;
  const double H = T + rowH * double(rows.size()) + B;
  auto X = [&](double v) { return L + (std::clamp(v, lo, hi) - lo) / (hi - lo) * (W - L - R); };
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
    << "' role='img'><text x='" << W / 2 << "' y='16' class='ttl'>" << html(title) << "</text>";
  for (double v = lo; v <= hi + 1e-9; v += step) {
    const double x = X(v);
    s << "<line x1='" << x << "' x2='" << x << "' y1='" << T - 4 << "' y2='" << H - B
      << "' class='grid'/><text x='" << x << "' y='" << H - 6 << "' class='tick'>"
      << fmt(v, valueFormat) << "</text>";
  }
  for (size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    const double y = T + rowH * double(i);
    s << "<text x='" << L - 6 << "' y='" << y + 11 << "' class='lbl' text-anchor='end'>"
      << html(r.c.id.size() > 20 ? r.c.id.substr(0, 19) + "…" : r.c.id) << "</text>";
    const double v = value(r);
    if (std::isnan(v)) {
      s << "<text x='" << L + 4 << "' y='" << y + 11 << "' class='lbl' fill='" << kBad << "'>"
        << html(r.status) << "</text>";
      continue;
    }
    s << "<rect x='" << L << "' y='" << y + 2 << "' width='" << std::max(1.0, X(v) - L)
      << "' height='" << rowH - 4 << "' fill='" << colour(v) << "'><title>" << html(r.c.id)
      << ": " << fmt(v, "%.4g") << unit << "</title></rect><text x='" << X(v) + 4 << "' y='"
      << y + 11 << "' class='lbl'>" << fmt(v, "%.3g") << "</text>";
  }
  const double x = X(ref);
  s << "<line x1='" << x << "' x2='" << x << "' y1='" << T - 4 << "' y2='" << H - B
    << "' class='ref'/></svg>";
  return s.str();
}

const char* kStyle = R"(body{font:14px/1.4 system-ui,sans-serif;margin:20px;color:#222}
h1{font-size:20px;margin:0 0 6px}p.meta{color:#555;margin:0 0 12px}
.plots{display:flex;flex-wrap:wrap;gap:14px;align-items:flex-start;margin-bottom:16px}
svg{background:#fafafa;border:1px solid #ddd}svg text{font:11px system-ui,sans-serif;fill:#333}
svg .ttl{font-weight:600;font-size:12px;text-anchor:middle}svg .tick{text-anchor:middle;fill:#666}
svg .axis{text-anchor:middle}svg .pt{font-size:10px;fill:#444}svg .frame{fill:none;stroke:#bbb}
svg .grid{stroke:#e4e4e4}svg .ref{stroke:#d62728;stroke-dasharray:4 3}
table{border-collapse:collapse;font-size:13px}th,td{border:1px solid #ddd;padding:3px 6px;
vertical-align:top}th{background:#f0f0f0;cursor:pointer;user-select:none;white-space:nowrap;
position:sticky;top:0}th.asc:after{content:" \25B2"}th.desc:after{content:" \25BC"}
td.num{text-align:right;font-variant-numeric:tabular-nums}tr.failed td,tr.canceled td,
tr.not_run td{background:#fde8e8}tr.poor_elements td{background:#fff4e0}
td.small{font-size:11px;color:#555;max-width:360px;overflow-wrap:anywhere}
)";

const char* kScript = R"(document.querySelectorAll('#cases th').forEach(function(th,col){
th.addEventListener('click',function(){var tb=document.querySelector('#cases tbody');
var asc=!th.classList.contains('asc');document.querySelectorAll('#cases th').forEach(
function(h){h.classList.remove('asc','desc')});th.classList.add(asc?'asc':'desc');
var num=th.dataset.num==='1';var rows=Array.prototype.slice.call(tb.rows);
rows.sort(function(a,b){var x=a.cells[col].dataset.v,y=b.cells[col].dataset.v;
if(x===''&&y==='')return 0;if(x==='')return 1;if(y==='')return -1;
var c=num?parseFloat(x)-parseFloat(y):x.localeCompare(y,undefined,{numeric:true});
return asc?c:-c});rows.forEach(function(r){tb.appendChild(r)})})});
)";

std::string htmlText(const std::vector<Row>& rows, const std::string& outDir,
                     const std::string& when) {
  std::map<std::string, int> byStatus;
  for (const auto& r : rows) ++byStatus[r.status];
  std::string counts;
  for (const auto& [st, n] : byStatus) counts += (counts.empty() ? "" : ", ") + std::to_string(n) + " " + st;
  std::ostringstream s;
  s << "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><title>FEMesher cohort "
       "summary</title><style>"
    << kStyle << "</style></head><body>\n<h1>FEMesher cohort summary</h1><p class='meta'>"
    << rows.size() << " cases (" << html(counts) << ") in " << html(outDir) << "; written "
    << html(when) << " by femesher " << FEMESHER_VERSION
    << ". Click a column header to sort. Bars: red below the dashed line (worst angle 10°, "
       "Dice 0.8), orange below 15° or Dice 0.9.</p>\n<div class='plots'>";
  s << scatterSvg(rows);
  s << barsSvg(rows, "Worst dihedral angle per case (degrees)", 0, 40, 10, 10, "°", "%.0f",
               [](const Row& r) { return r.worst; },
               [](double v) { return v < 10 ? kBad : v < 15 ? kFair : kGood; });
  double lo = 1;
  for (const auto& r : rows)
    if (!std::isnan(r.minDice)) lo = std::min(lo, r.minDice);
  lo = std::min(0.8, std::floor(lo * 10) / 10);
  s << barsSvg(rows, "Lowest volume Dice per case", lo, 1.0, 1.0 - lo > 0.25 ? 0.1 : 0.05, 0.8,
               "", "%.2f",
               [](const Row& r) { return r.minDice; },
               [](double v) { return v < 0.8 ? kBad : v < 0.9 ? kFair : kGood; });
  s << "</div>\n<table id='cases'><thead><tr>";
  const std::pair<const char*, bool> cols[] = {
      {"case", false},        {"status", false},     {"exit", true},     {"run", false},
      {"wall s", true},       {"tets", true},        {"worst °", true},  {"% < 10°", true},
      {"min Dice", true},     {"Dice per label", false}, {"missing labels", false},
      {"warnings", true},     {"error / warnings", false}};
  for (const auto& [name, num] : cols)
    s << "<th data-num='" << (num ? 1 : 0) << "'>" << html(name) << "</th>";
  s << "</tr></thead><tbody>\n";
  auto cell = [&](const std::string& v, const std::string& shown, const char* cls) {
    s << "<td class='" << cls << "' data-v='" << html(v) << "'>" << html(shown) << "</td>";
  };
  // Long texts (warnings naming 40 materials) are cut in the cell; the whole text is its tooltip
  // and in summary.csv / summary.json.
  auto longCell = [&](const std::vector<std::string>& parts, const std::string& sep) {
    std::string shown, full = joined(parts, sep);
    for (const auto& p : parts)
      shown += (shown.empty() ? "" : sep) + (p.size() > 160 ? p.substr(0, 150) + " …" : p);
    s << "<td class='small' data-v='" << html(full) << "' title='" << html(full) << "'>"
      << html(shown) << "</td>";
  };
  for (const auto& r : rows) {
    s << "<tr class='" << html(r.status) << "'>";
    cell(r.c.id, r.c.id, "");
    cell(r.status, r.status, "");
    const std::string exit = r.c.exitCode < 0 ? "" : std::to_string(r.c.exitCode);
    cell(exit, exit, "num");
    cell(r.c.run, r.c.run, "");
    const double wall = r.c.wallSeconds < 0 ? kNaN : r.c.wallSeconds;
    cell(fmt(wall, "%.3f"), fmt(wall, "%.1f"), "num");
    const std::string tets = r.tets < 0 ? "" : std::to_string(r.tets);
    cell(tets, tets, "num");
    cell(fmt(r.worst, "%.4f"), fmt(r.worst, "%.2f"), "num");
    cell(fmt(r.below10, "%.5f"), fmt(r.below10, "%.3f"), "num");
    cell(fmt(r.minDice, "%.5f"),
         fmt(r.minDice, "%.4f") + (r.minDiceLabel.empty() ? "" : " (" + r.minDiceLabel + ")"),
         "num");
    std::vector<std::string> dice;
    for (const auto& [l, d] : r.dice) dice.push_back(l + ": " + fmt(d, "%.3f"));
    longCell(dice, ", ");
    cell(joined(r.missing, "; "), joined(r.missing, "; "), "small");
    cell(std::to_string(r.warnings.size()), std::to_string(r.warnings.size()), "num");
    longCell(r.c.error.empty() ? r.warnings : std::vector<std::string>{r.c.error}, " | ");
    s << "</tr>\n";
  }
  s << "</tbody></table>\n<script>" << kScript << "</script>\n</body></html>\n";
  return s.str();
}

Status writeFile(const std::string& path, const std::string& text) {
  return writeAtomically(path, [path, text](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out << text;
    out.close();
    if (!out) return Status(ErrorCode::WriteFailed, "Cannot write '" + path + "'.");
    return Status::ok();
  });
}

}  // namespace

std::string lastLines(const std::string& path, int lines) {
  std::ifstream in(path);
  std::vector<std::string> all;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // A terminal bar's redraws end with '\r': keep the last state of such a line.
    if (const auto cr = line.rfind('\r'); cr != std::string::npos) line = line.substr(cr + 1);
    if (line.find_first_not_of(" \t") != std::string::npos) all.push_back(line);
  }
  const size_t from = all.size() > size_t(lines) ? all.size() - size_t(lines) : 0;
  std::string o;
  for (size_t i = from; i < all.size(); ++i) o += (o.empty() ? "" : "\n") + all[i];
  return o;
}

std::string errorOf(const std::string& logPath) {
  const std::string tail = lastLines(logPath, 5);
  size_t from = tail.rfind("\nerror");
  if (tail.rfind("error", 0) == 0 && from == std::string::npos) from = 0;
  else if (from != std::string::npos) ++from;
  return from == std::string::npos ? tail : tail.substr(from);
}

std::vector<CaseRecord> scanCaseFolders(const std::string& outDir) {
  std::vector<CaseRecord> cases;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(outDir, ec)) {
    if (!entry.is_directory()) continue;
    const fs::path dir = entry.path();
    const bool record = fs::exists(dir / kCaseRecord), report = fs::exists(dir / kCaseReport);
    if (!record && !report && !fs::exists(dir / kCaseLog)) continue;
    CaseRecord c;
    c.id = dir.filename().string();
    c.dir = dir.string();
    const json rec = record ? readJson((dir / kCaseRecord).string()) : json();
    if (rec.is_object()) {
      c.exitCode = rec.value("exit_code", -1);
      c.wallSeconds = rec.value("wall_seconds", -1.0);
      c.input = rec.value("input", std::string());
      c.error = rec.value("error", std::string());
    }
    const json rep = report ? readJson((dir / kCaseReport).string()) : json();
    if (rep.is_object()) {
      if (c.exitCode < 0) c.exitCode = 0;
      if (c.wallSeconds < 0) c.wallSeconds = rep.value("total_seconds", -1.0);
      if (c.input.empty() && rep.contains("input")) c.input = rep["input"].value("path", "");
    }
    c.status = c.exitCode == 0 && rep.is_object() ? "ok" : "failed";
    c.run = c.exitCode < 0 ? "not_run" : "meshed";
    if (c.status == "failed" && c.error.empty()) c.error = errorOf((dir / kCaseLog).string());
    cases.push_back(c);
  }
  std::sort(cases.begin(), cases.end(),
            [](const CaseRecord& a, const CaseRecord& b) { return a.id < b.id; });
  return cases;
}

Status writeCohortSummary(const std::string& outDir, const std::vector<CaseRecord>& cases) {
  std::vector<Row> rows;
  for (const auto& c : cases) rows.push_back(makeRow(c));
  const std::time_t now = std::time(nullptr);
  char when[64];
  std::strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S UTC", std::gmtime(&now));
  const fs::path dir(outDir);
  if (Status s = writeFile((dir / "summary.csv").string(), csvText(rows)); !s) return s;
  if (Status s = writeFile((dir / "summary.json").string(), jsonText(rows, when) + "\n"); !s)
    return s;
  return writeFile((dir / "summary.html").string(), htmlText(rows, outDir, when));
}

}  // namespace femesher::cli
