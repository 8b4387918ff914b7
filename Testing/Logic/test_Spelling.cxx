// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parameters.h>
#include <femesher/Spelling.h>

#include <gtest/gtest.h>

using namespace femesher;

TEST(Spelling, EditDistanceCountsEachEditOnce) {
  EXPECT_EQ(editDistance("", ""), 0u);
  EXPECT_EQ(editDistance("abc", ""), 3u);
  EXPECT_EQ(editDistance("", "abc"), 3u);
  EXPECT_EQ(editDistance("mesh", "mesh"), 0u);
  EXPECT_EQ(editDistance("mesh", "mseh"), 1u);      // adjacent swap
  EXPECT_EQ(editDistance("length", "lenght"), 1u);  // adjacent swap
  EXPECT_EQ(editDistance("refinement", "refinment"), 1u);  // deletion
  EXPECT_EQ(editDistance("kitten", "sitting"), 3u);
  EXPECT_EQ(editDistance("ca", "abc"), 3u);  // optimal string alignment, not full Damerau (2)
  // Symmetric.
  EXPECT_EQ(editDistance("density", "densty"), editDistance("densty", "density"));
}

TEST(Spelling, ClosestNameOnlyForCloseMatches) {
  const std::vector<std::string> known = {"edge_length_factor", "target_edge_length", "seed"};
  EXPECT_EQ(closestName("edge_lenght_factor", known), "edge_length_factor");
  EXPECT_EQ(closestName("target_edge_lenth", known), "target_edge_length");
  EXPECT_EQ(closestName("sed", known), "seed");         // one edit on a short word
  EXPECT_EQ(closestName("sd", known), "");              // two edits on a short word: too far
  EXPECT_EQ(closestName("zzzzzzzz", known), "");
  EXPECT_EQ(closestName("seed", known), "");            // a known name needs no suggestion
  EXPECT_EQ(didYouMean("sed", known), " Did you mean 'seed'?");
  EXPECT_EQ(didYouMean("xyz", known), "");
}

TEST(Spelling, SetParameterSuggestsKeysAndMaterialFields) {
  MeshingParameters p;
  Status s = setParameter(p, "edge_lenght_factor", "3");
  EXPECT_EQ(s.code(), ErrorCode::InvalidArgument);
  EXPECT_NE(s.message().find("Did you mean 'edge_length_factor'?"), std::string::npos) << s.message();
  s = setParameter(p, "material.2.densty", "1e-9");
  EXPECT_EQ(s.code(), ErrorCode::InvalidArgument);
  EXPECT_NE(s.message().find("Did you mean 'density'?"), std::string::npos) << s.message();
  s = setParameter(p, "materal.2.E", "500");
  EXPECT_NE(s.message().find("Did you mean 'material.2.E'?"), std::string::npos) << s.message();
  s = setParameter(p, "qqqqqqqqqq", "1");
  EXPECT_EQ(s.code(), ErrorCode::InvalidArgument);
  EXPECT_EQ(s.message().find("Did you mean"), std::string::npos) << s.message();
}
