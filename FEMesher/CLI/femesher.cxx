// SPDX-License-Identifier: GPL-3.0-or-later
#include "FEMesherXml.h"
#include <cstdio>
int main() { std::puts(kFEMesherCliXml); return 0; }
