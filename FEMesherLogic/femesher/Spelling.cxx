// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Spelling.h>

#include <algorithm>

namespace femesher {

size_t editDistance(const std::string& a, const std::string& b) {
  const size_t n = a.size(), m = b.size();
  // Three rows of the (n+1) x (m+1) table: two back for the transposition.
  std::vector<size_t> prev2(m + 1), prev(m + 1), cur(m + 1);
  for (size_t j = 0; j <= m; ++j) prev[j] = j;
  for (size_t i = 1; i <= n; ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= m; ++j) {
      const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        cur[j] = std::min(cur[j], prev2[j - 2] + 1);
    }
    std::swap(prev2, prev);
    std::swap(prev, cur);
  }
  return prev[m];
}

std::string closestName(const std::string& word, const std::vector<std::string>& known) {
  if (std::find(known.begin(), known.end(), word) != known.end()) return {};
  const size_t allowed = std::min<size_t>(2, std::max<size_t>(1, word.size() / 3));
  std::string best;
  size_t bestDistance = allowed + 1;
  for (const auto& k : known) {
    const size_t d = editDistance(word, k);
    if (d < bestDistance) {
      bestDistance = d;
      best = k;
    }
  }
  return best;
}

std::string didYouMean(const std::string& word, const std::vector<std::string>& known) {
  const std::string name = closestName(word, known);
  return name.empty() ? std::string() : " Did you mean '" + name + "'?";
}

}  // namespace femesher
