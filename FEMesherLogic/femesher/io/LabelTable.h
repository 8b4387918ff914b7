// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelTable.h
/// Colour tables that name the labels of a label map (`femesher mesh --label-names FILE`), for
/// label maps that cannot carry names themselves (NIfTI, plain NRRD, MetaImage). Three formats,
/// told apart by their content:
///  - 3D Slicer's colour table file (.ctbl, .txt): '#' comment lines, then one line per entry
///    "label name R G B A", colour components 0..255; Slicer writes spaces in names as
///    underscores, which are kept as they are.
///  - 3D Slicer's colour table CSV file (.csv): a header line with the columns LabelValue and
///    Name (and optionally Color_R, Color_G, Color_B, Color_A, 0..255), one entry per line;
///    values holding a comma are quoted with '"'.
///  - ITK-SNAP's label description file: '#' comment lines, then
///    `IDX R G B A VIS MSH "LABEL"` per entry (R, G, B 0..255, A 0..1, the name in quotes).
/// Entry 0 (Slicer's and ITK-SNAP's "Background" / "Clear Label") is read like any other; it only
/// names a material in a label map without background.

#include <femesher/Status.h>
#include <femesher/Types.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace femesher {

struct LabelTableEntry {
  int32_t label = 0;
  std::string name;                        ///< as in the file (quotes removed), never empty
  std::array<double, 3> color{{0, 0, 0}};  ///< RGB in [0, 1], when `hasColor`
  bool hasColor = false;
  int line = 0;  ///< 1-based line of the file (for messages)
};

/// Reads a colour table. Errors: FileNotFound; UnreadableFile for a folder or a file with no
/// entry; CorruptFile naming the line for a malformed entry (a label that is not an integer, a
/// missing name, a colour component out of range, an unterminated quote, a label given twice).
Result<std::vector<LabelTableEntry>> readLabelTable(const std::string& path);

/// Names (and colours) the materials of `volume` from `table`: a material whose label has an
/// entry takes its name and colour, as the names a .seg.nrrd carries would (the user's
/// `material.<label>.name` still overrides them). Entries for labels the map does not have are
/// ignored (a generic table may list many more). InvalidArgument when not one entry matches a
/// material of the map: the table names the file and lists the labels of both.
Status applyLabelTable(LabelVolume& volume, const std::vector<LabelTableEntry>& table,
                       const std::string& tablePath);

}  // namespace femesher
