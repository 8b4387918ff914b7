// SPDX-License-Identifier: GPL-3.0-or-later
// (filled in by the CLI implementation)
