// SPDX-License-Identifier: GPL-3.0-or-later
#include "SlicerXml.h"

#include <femesher/Parameters.h>
#include <femesher/Version.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace femesher::cli {

namespace {

std::string xmlEscape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else o += c;
  }
  return o;
}


/// Digits after the '.', as Slicer counts them to choose a spin box's decimals.
int decimalsOf(const std::string& text) {
  const auto dot = text.find('.');
  return dot == std::string::npos ? 0 : int(text.size() - dot - 1);
}

/// "1" followed by `e` zeros (e >= 0) or "0.0..01" with the 1 at the -e-th decimal.
std::string powerOfTen(int e) {
  if (e >= 0) return "1" + std::string(size_t(e), '0');
  return "0." + std::string(size_t(-e - 1), '0') + "1";
}

/// Slider step for a double: at least 0.01 and as fine as the numbers written for the parameter,
/// coarsened until the range fits the int positions of Slicer's ctkDoubleSlider.
std::string doubleStep(const ParameterDescriptor& d, const std::string& def, const std::string& mn,
                       const std::string& mx) {
  int e = -std::max({2, decimalsOf(def), decimalsOf(mn), decimalsOf(mx)});
  const double extent = std::max(std::fabs(d.minimum), std::fabs(d.maximum));
  while (extent / std::pow(10.0, e) > double(std::numeric_limits<int32_t>::max())) ++e;
  return powerOfTen(e);
}

/// Slicer prints a constrained integer's value as a double with 6 significant digits: exact for
/// every integer within +-1,000,000.
bool integerSliderIsExact(const ParameterDescriptor& d) {
  return std::fabs(d.minimum) <= 1e6 && std::fabs(d.maximum) <= 1e6;
}

std::string integerText(double v) { return std::to_string(int64_t(v)); }

void writeParameter(std::ostringstream& x, const ParameterDescriptor& d) {
  std::string name = semName(d.key), label = d.label, help = d.help, tag, def;
  if (d.type == "bool") {
    tag = "boolean";
    def = "false";
    if (d.defaultValue == "1") {  // on by default: Slicer can only pass "true", so offer "off"
      name = "no_" + name;
      label = "Turn off: " + label;
      help = "Tick to turn this off (it is on by default). " + help;
    }
  } else if (d.type == "choice") {
    tag = "string-enumeration";
    def = d.defaultValue;
  } else if (d.type == "int") {
    tag = "integer";
  } else if (d.type == "double") {
    tag = "double";
  } else if (d.type == "string") {
    tag = "string";  // free text; Slicer passes it only when the field is not empty
    def = xmlEscape(d.defaultValue);
  } else {
    throw std::logic_error("slicerXml: parameter '" + d.key + "' has unknown type " + d.type);
  }
  std::string mn, mx, step;
  bool constraints = false;
  if (d.type == "int") {
    def = integerText(std::stod(d.defaultValue));
    constraints = integerSliderIsExact(d);
    mn = integerText(d.minimum);
    mx = integerText(d.maximum);
    step = "1";
    if (!constraints) help += " Range " + mn + " to " + mx + ".";
  } else if (d.type == "double") {
    def = plainDecimal(std::stod(d.defaultValue));
    mn = plainDecimal(d.minimum);
    mx = plainDecimal(d.maximum);
    step = doubleStep(d, def, mn, mx);
    constraints = true;
  }
  if (!d.unit.empty()) help += " Unit: " + d.unit + ".";
  x << "    <" << tag << ">\n      <name>" << name << "</name>\n      <label>" << xmlEscape(label)
    << "</label>\n      <longflag>--" << name << "</longflag>\n      <description>"
    << xmlEscape(help) << "</description>\n      <default>" << def << "</default>\n";
  for (const auto& c : d.choices) x << "      <element>" << c << "</element>\n";
  if (constraints)
    x << "      <constraints>\n        <minimum>" << mn << "</minimum>\n        <maximum>" << mx
      << "</maximum>\n        <step>" << step << "</step>\n      </constraints>\n";
  x << "    </" << tag << ">\n";
}

}  // namespace

std::string plainDecimal(double value) {
  char buf[400];
  const auto r = std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed);
  if (r.ec != std::errc()) throw std::logic_error("plainDecimal: cannot format a number");
  std::string s(buf, r.ptr);
  return s == "-0" ? "0" : s;
}

std::string semName(const std::string& key) {
  std::string n = key;
  for (auto& c : n)
    if (c == '.' || c == '-') c = '_';
  return n;
}

std::string slicerXml() {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<executable>\n"
    << "  <category>Segmentation</category>\n  <title>FEMesher</title>\n"
    << "  <description>Conformal multi-material tetrahedral mesh (FE-ready) from a label map: every "
       "tet carries its material, neighbouring materials share the same interface triangles."
       "</description>\n"
    << "  <version>" FEMESHER_VERSION "</version>\n"
    << "  <documentation-url>https://github.com/femesher/FEMesher</documentation-url>\n"
    << "  <license>GPL-3.0-or-later</license>\n  <contributor>FEMesher developers</contributor>\n"
    << "  <acknowledgements>Method after Kehl et al. (BioMesh3D particle pipeline with the "
       "Integer Medial Axis).</acknowledgements>\n"
    << "  <parameters>\n    <label>IO</label>\n    <description>Input label map and output mesh"
       "</description>\n"
    << "    <image type=\"label\">\n      <name>inputVolume</name>\n      <label>Label map</label>\n"
       "      <channel>input</channel>\n      <index>0</index>\n"
       "      <description>Segmentation as a label map (one integer material id per voxel)"
       "</description>\n    </image>\n"
    << "    <geometry type=\"model\" fileExtensions=\".vtu,.vtk\">\n      <name>outputMesh</name>\n"
       "      <label>Tetrahedral mesh</label>\n      <channel>output</channel>\n"
       "      <index>1</index>\n      <description>Labelled tetrahedral mesh (cell array "
       "'labels', LPS)</description>\n    </geometry>\n"
    << "    <file fileExtensions=\".ctbl,.txt,.csv,.label\">\n      <name>labelNames</name>\n"
       "      <label>Label names</label>\n      <longflag>--label_names</longflag>\n"
       "      <channel>input</channel>\n      <description>Optional colour table naming the "
       "labels (3D Slicer .ctbl or .csv, ITK-SNAP label description); the names go into every "
       "mesh format that holds names</description>\n    </file>\n  </parameters>\n";
  for (bool advanced : {false, true}) {
    x << "  <parameters" << (advanced ? " advanced=\"true\"" : "") << ">\n    <label>"
      << (advanced ? "Advanced" : "Meshing") << "</label>\n    <description>"
      << (advanced ? "Quality bounds, smoothing, material properties, run options"
                   : "Element size and what is meshed")
      << "</description>\n";
    for (const auto& d : parameterDescriptors())
      if (d.advanced == advanced) writeParameter(x, d);
    x << "  </parameters>\n";
  }
  x << "</executable>\n";
  return x.str();
}

}  // namespace femesher::cli
