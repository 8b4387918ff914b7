// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// "Did you mean": the closest known name to a misspelt one (parameter keys, material fields, CLI
// flags and subcommands).
#include <string>
#include <vector>

namespace femesher {

/// Edit distance between `a` and `b` counting insertions, deletions, substitutions and swaps of
/// two adjacent characters as one edit each (optimal string alignment, a restricted
/// Damerau-Levenshtein distance). Case-sensitive, byte-wise.
size_t editDistance(const std::string& a, const std::string& b);

/// The name in `known` closest to `word` when it is close enough to be a likely misspelling: at
/// most 2 edits and at most a third of `word`'s length (at least 1 edit allowed). On a tie the
/// first in `known` wins. Empty when nothing is that close, or when `word` is itself in `known`.
std::string closestName(const std::string& word, const std::vector<std::string>& known);

/// " Did you mean 'NAME'?" for closestName(word, known), or "" when there is none.
std::string didYouMean(const std::string& word, const std::vector<std::string>& known);

}  // namespace femesher
