# SPDX-License-Identifier: GPL-3.0-or-later
"""ExtensionDescription.txt (Slicer .s4ext syntax) agrees with the EXTENSION_* variables of the
top-level CMakeLists.txt, has every field Slicer requires, and no syntax Slicer rejects."""
import os
import re
import sys
import unittest

SOURCE = os.environ.get("FEMESHER_SOURCE_DIR") or os.path.join(os.path.dirname(__file__), "..", "..")

# Required and optional keys (Slicer's Extensions/CMake/SlicerExtensionDescriptionSpec.cmake).
REQUIRED = {"scm", "scmurl", "scmrevision"}
KNOWN = REQUIRED | {"depends", "recommends", "build_subdirectory", "homepage", "contributors",
                    "category", "iconurl", "description", "screenshoturls", "enabled", "status",
                    "tier", "dicom_support_rule", "keywords"}
# s4ext key -> CMake variable
CMAKE_VARS = {"homepage": "EXTENSION_HOMEPAGE", "category": "EXTENSION_CATEGORY",
              "contributors": "EXTENSION_CONTRIBUTORS", "description": "EXTENSION_DESCRIPTION",
              "depends": "EXTENSION_DEPENDS", "iconurl": "EXTENSION_ICONURL",
              "screenshoturls": "EXTENSION_SCREENSHOTURLS", "status": "EXTENSION_STATUS",
              "build_subdirectory": "EXTENSION_BUILD_SUBDIRECTORY"}


def read_cmake_vars(path):
    text = open(path, encoding="utf-8").read()
    out = {}
    for m in re.finditer(r'^\s*set\(\s*(EXTENSION_\w+)\s+(.*?)\)\s*$', text, re.M):
        value = m.group(2).strip()
        if value.startswith('"') and value.endswith('"'):
            value = value[1:-1]
        out[m.group(1)] = value
    return out


def read_s4ext(path):
    fields, problems = {}, []
    for n, line in enumerate(open(path, encoding="utf-8"), 1):
        line = line.rstrip("\n")
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        key, _, value = line.partition(" ")
        if key in fields:
            problems.append(f"line {n}: '{key}' given twice")
        fields[key] = value.strip()
    return fields, problems


class ExtensionDescriptionTest(unittest.TestCase):
    def setUp(self):
        self.cmake = read_cmake_vars(os.path.join(SOURCE, "CMakeLists.txt"))
        self.fields, self.problems = read_s4ext(os.path.join(SOURCE, "ExtensionDescription.txt"))

    def test_syntax(self):
        self.assertEqual(self.problems, [])
        for key, value in self.fields.items():
            self.assertIn(key, KNOWN, f"unknown .s4ext keyword '{key}'")
            self.assertTrue(value, f"'{key}' has no value")
            if key.endswith("url") or key.endswith("urls") or key == "homepage":
                self.assertNotIn("&", value, f"'{key}': Slicer rejects '&' in URLs")
        self.assertTrue(REQUIRED <= set(self.fields), f"missing {REQUIRED - set(self.fields)}")
        self.assertIn(self.fields.get("enabled", "1"), {"0", "1"})

    def test_agrees_with_cmake(self):
        self.assertEqual(self.cmake.get("EXTENSION_NAME"), "FEMesher")
        checked = 0
        for key, var in CMAKE_VARS.items():
            if var in self.cmake:
                self.assertIn(key, self.fields, f"{var} is set in CMakeLists.txt but '{key}' is missing")
                self.assertEqual(self.fields[key], self.cmake[var], f"'{key}' differs from {var}")
                checked += 1
        self.assertGreaterEqual(checked, 5, "too few EXTENSION_* variables found in CMakeLists.txt")

    def test_icon_and_screenshot_exist_in_the_tree(self):
        for key, rel in (("iconurl", "Resources/Icons/FEMesher.png"),):
            self.assertTrue(self.fields[key].endswith(rel))
            self.assertTrue(os.path.isfile(os.path.join(SOURCE, rel)), rel)
        for url in self.fields.get("screenshoturls", "").split():
            rel = url.split("/main/", 1)[-1]
            self.assertTrue(os.path.isfile(os.path.join(SOURCE, rel)), rel)


if __name__ == "__main__":
    sys.exit(0 if unittest.main(exit=False).result.wasSuccessful() else 1)
