// SPDX-License-Identifier: GPL-3.0-or-later
// Curving after the run (DeferredCurving): a run at element order 1 keeps what the curving needs,
// and curving its mesh afterwards gives exactly the mid-edge nodes a run at element order 2
// curves (the same map, bit for bit, and the same .inp bytes), also with a contact pair (node
// copies); the nodes are computed once; a run at order 2 keeps nothing.
#include <femesher/Parameters.h>
#include <femesher/Phantom.h>
#include <femesher/Pipeline.h>
#include <femesher/io/MeshIO.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;
using namespace femesher;

namespace {

std::string fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void expectDeferredAsOrderTwo(const std::string& contactPairs) {
  SCOPED_TRACE("contact_pairs '" + contactPairs + "'");
  const LabelVolume input = makePhantom();
  MeshingParameters p1;
  ASSERT_TRUE(setParameter(p1, "contact_pairs", contactPairs).isOk());
  MeshingParameters p2 = p1;
  p2.elementOrder = 2;
  RunContext c1, c2;
  PipelineOptions keep;
  keep.keepCurvingData = true;  // what the panel asks for
  auto r1 = runPipeline(input, p1, c1, keep);
  auto r2 = runPipeline(input, p2, c2, keep);
  ASSERT_TRUE(r1.isOk()) << r1.status().message();
  ASSERT_TRUE(r2.isOk()) << r2.status().message();
  ASSERT_FALSE(r1->midEdgeNodes);
  ASSERT_TRUE(r1->deferredCurving);
  ASSERT_TRUE(r2->midEdgeNodes);
  EXPECT_FALSE(r2->deferredCurving) << "an order-2 run has its nodes: nothing to keep";
  // The element order changes nothing before the curving.
  ASSERT_EQ(r1->mesh.points, r2->mesh.points);
  ASSERT_EQ(r1->mesh.tets, r2->mesh.tets);
  if (!contactPairs.empty()) EXPECT_FALSE(r1->contacts.empty());

  RunContext later;
  const auto nodes = r1->deferredCurving->midEdgeNodes(r1->mesh, later);
  ASSERT_TRUE(nodes);
  EXPECT_GT(nodes->size(), 100u) << "the phantom has curved interface nodes";
  EXPECT_EQ(*nodes, *r2->midEdgeNodes) << "not the nodes of the order-2 run";
  EXPECT_EQ(r1->deferredCurving->midEdgeNodes(r1->mesh, later), nodes) << "curved once";
  std::map<std::string, double> counts(r2->counts.begin(), r2->counts.end());
  const QuadraticCurvingResult f = r1->deferredCurving->figures();
  EXPECT_EQ(double(f.curvedNodes), counts.at("quadratic_curved_nodes"));
  EXPECT_EQ(double(f.partlyCurvedNodes), counts.at("quadratic_partly_curved_nodes"));
  EXPECT_EQ(double(f.straightKept), counts.at("quadratic_straight_kept"));
  EXPECT_GT(r1->deferredCurving->memoryBytes(), r1->mesh.tets.size() * sizeof(r1->mesh.tets[0]));

  // The same deck, byte for byte.
  const fs::path dir = fs::path(FEMESHER_TEST_TMP_DIR) / "quadratic_deferred";
  fs::create_directories(dir);
  ExportOptions o1 = exportOptionsFrom(p2);
  o1.contacts = r1->contacts;
  o1.nodeSets = r1->boxNodeSets;
  o1.midEdgeNodes = nodes;
  ExportOptions o2 = exportOptionsFrom(p2);
  o2.contacts = r2->contacts;
  o2.nodeSets = r2->boxNodeSets;
  o2.midEdgeNodes = r2->midEdgeNodes;
  const fs::path a = dir / ("deferred" + std::to_string(contactPairs.size()) + ".inp");
  const fs::path b = dir / ("order2" + std::to_string(contactPairs.size()) + ".inp");
  ASSERT_TRUE(writeMesh(r1->mesh, a.string(), o1).isOk());
  ASSERT_TRUE(writeMesh(r2->mesh, b.string(), o2).isOk());
  const std::string bytes = fileBytes(a);
  EXPECT_GT(bytes.size(), 1000u);
  EXPECT_TRUE(bytes == fileBytes(b)) << a << " and " << b << " differ";
}

}  // namespace

TEST(QuadraticDeferred, OrderOneRunCurvedLaterAsAnOrderTwoRun) { expectDeferredAsOrderTwo(""); }

TEST(QuadraticDeferred, WithAContactPairTheCopiesGetTheirNodes) { expectDeferredAsOrderTwo("4:1"); }

TEST(QuadraticDeferred, KeptOnlyWhenTheHostAsks) {
  // The CLI's call (default options) keeps nothing: the same mesh, no deferred curving.
  const LabelVolume input = makePhantom();
  MeshingParameters p;
  p.run.computeFidelity = false;
  RunContext c1, c2;
  PipelineOptions keep;
  keep.keepCurvingData = true;
  auto plain = runPipeline(input, p, c1);
  auto kept = runPipeline(input, p, c2, keep);
  ASSERT_TRUE(plain.isOk()) << plain.status().message();
  ASSERT_TRUE(kept.isOk()) << kept.status().message();
  EXPECT_FALSE(plain->deferredCurving);
  EXPECT_FALSE(plain->midEdgeNodes);
  ASSERT_TRUE(kept->deferredCurving);
  EXPECT_EQ(plain->mesh.tets, kept->mesh.tets);
  EXPECT_EQ(plain->mesh.points, kept->mesh.points);
}
