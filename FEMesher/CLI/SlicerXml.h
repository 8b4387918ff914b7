// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file SlicerXml.h
/// `femesher --xml`: the Slicer Execution Model (SEM) description of the CLI module, generated
/// from `parameterDescriptors()` so that the XML and the accepted flags cannot drift apart.
///
/// It follows what Slicer does with the XML (SlicerExecutionModel's ModuleDescriptionParser,
/// Slicer's qSlicerCLIModuleUIHelper and vtkSlicerCLIModuleLogic):
///  - `<name>` and `<longflag>` hold only letters, digits and underscores (the parser rejects the
///    whole description otherwise), so flags are the parameter keys with '.' -> '_'
///    (`--min_voxels`, `--default_E`); femesher accepts them beside the hyphenated spellings.
///  - Slicer passes a boolean as a bare flag when it is true and omits it when false, so every
///    `<boolean>` defaults to false: a parameter that is on by default appears as its negation
///    (`--no_voxel_refinement`), one that is off by default as itself (`--volume_sizing`).
///  - Integers are read with QString::toInt and, with `<constraints>`, shown in a slider whose
///    value Slicer prints as a double with 6 significant digits: they are written as plain
///    integers, and constraints are given only when the range lies within +-1,000,000 (printed
///    exactly); wider ones (the seed) get a spin box without constraints, which Slicer prints as
///    an int.
///  - Doubles: the panel shows as many decimals as the default, minimum, maximum or step has
///    after its '.', so numbers are written in plain decimal notation, never with an exponent
///    (`1e-09` would show as 0.00), and each has a `<step>` of at least 0.01 resolution.
///  - There is no preset selector: Slicer passes every numeric parameter at its panel value,
///    which would override any preset; the presets stay on the command line and in the panel.

#include <string>

namespace femesher::cli {

/// Parameter key -> SEM `<name>` and long flag: '.' and '-' become '_' (letters, digits and
/// underscores only): "default.E" -> "default_E". femesher accepts these flags beside the
/// hyphenated ones.
std::string semName(const std::string& key);

/// The whole `<executable>` document.
std::string slicerXml();

/// `value` in plain decimal notation (never an exponent), the shortest text that reads back to
/// the same double: 1e-9 -> "0.000000001", 1e9 -> "1000000000", 0.3 -> "0.3".
std::string plainDecimal(double value);

}  // namespace femesher::cli
