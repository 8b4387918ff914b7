// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parameters.h>
#include <femesher/StageTable.h>
#include <femesher/RunContext.h>
#include <femesher/Types.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <set>
#include <thread>

using namespace femesher;

TEST(Parameters, SetAndGetEveryDescriptor) {
  MeshingParameters p;
  for (const auto& d : parameterDescriptors()) {
    EXPECT_EQ(getParameter(p, d.key), d.type == "bool" ? (d.defaultValue == "1" ? "true" : "false")
                                                       : d.defaultValue)
        << d.key;
    EXPECT_FALSE(d.help.empty()) << d.key;
  }
  ASSERT_TRUE(setParameter(p, "target_edge_length", "1.5").isOk());
  EXPECT_DOUBLE_EQ(p.sizing.targetEdgeLength, 1.5);
  ASSERT_TRUE(setParameter(p, "preserve_interfaces", "off").isOk());
  EXPECT_FALSE(p.volume.preserveInterfaces);
}

TEST(Parameters, BooleanWords) {
  bool b = false;
  for (const char* t : {"true", "on", "yes", "1"}) {
    b = false;
    EXPECT_TRUE(parseBoolean(t, b)) << t;
    EXPECT_TRUE(b) << t;
  }
  for (const char* f : {"false", "off", "no", "0"}) {
    b = true;
    EXPECT_TRUE(parseBoolean(f, b)) << f;
    EXPECT_FALSE(b) << f;
  }
  b = true;
  for (const char* bad : {"", "True", "2", "input.nrrd", "--x"}) {
    EXPECT_FALSE(parseBoolean(bad, b)) << bad;
    EXPECT_TRUE(b) << "left alone on " << bad;
  }
}

TEST(Parameters, DescriptorJsonHoldsTheRegistryExactly) {
  const auto j = nlohmann::json::parse(parameterDescriptorsToJson());
  const auto& descriptors = parameterDescriptors();
  ASSERT_EQ(j.size(), descriptors.size());
  const MeshingParameters defaults;
  for (size_t i = 0; i < descriptors.size(); ++i) {
    const auto& d = descriptors[i];
    const auto& e = j[i];
    EXPECT_EQ(e["key"], d.key);
    EXPECT_EQ(e["type"], d.type);
    if (d.type == "bool") {
      ASSERT_TRUE(e["default"].is_boolean()) << d.key;
      EXPECT_EQ(e["default"].get<bool>() ? "true" : "false", getParameter(defaults, d.key));
    } else if (d.type == "choice") {
      EXPECT_EQ(e["default"], getParameter(defaults, d.key));
      EXPECT_EQ(e["choices"].get<std::vector<std::string>>(), d.choices);
    } else if (d.type == "string") {
      // Free text (contact_pairs): the default as text, set back unchanged; no range or choices.
      ASSERT_TRUE(e["default"].is_string()) << d.key;
      EXPECT_EQ(e["default"].get<std::string>(), getParameter(defaults, d.key)) << d.key;
      EXPECT_FALSE(e.contains("choices") || e.contains("minimum")) << d.key;
      MeshingParameters p;
      ASSERT_TRUE(setParameter(p, d.key, e["default"].get<std::string>()).isOk()) << d.key;
      EXPECT_EQ(getParameter(p, d.key), getParameter(defaults, d.key)) << d.key;
    } else {
      // The default, set back through setParameter as JSON text, gives the same parameters.
      MeshingParameters p;
      ASSERT_TRUE(setParameter(p, d.key, e["default"].dump()).isOk()) << d.key;
      EXPECT_EQ(getParameter(p, d.key), getParameter(defaults, d.key)) << d.key;
      EXPECT_EQ(e["minimum"].get<double>(), d.minimum) << d.key;
      EXPECT_EQ(e["maximum"].get<double>(), d.maximum) << d.key;
      EXPECT_EQ(e["default"].is_number_integer(), d.type == "int") << d.key;
      EXPECT_TRUE(setParameter(p, d.key, e["maximum"].dump()).isOk()) << d.key;
    }
  }
}

TEST(Parameters, RejectsUnknownKeysAndBadValues) {
  MeshingParameters p;
  Status s = setParameter(p, "no_such_key", "1");
  EXPECT_EQ(s.code(), ErrorCode::InvalidArgument);
  EXPECT_NE(s.message().find("no_such_key"), std::string::npos);
  EXPECT_EQ(setParameter(p, "min_voxels", "1.5").code(), ErrorCode::InvalidArgument);
  EXPECT_EQ(setParameter(p, "min_voxels", "abc").code(), ErrorCode::InvalidArgument);
  EXPECT_EQ(setParameter(p, "min_dihedral_angle", "40").code(), ErrorCode::InvalidArgument);
  EXPECT_EQ(setParameter(p, "material.3.nu", "0.7").code(), ErrorCode::InvalidArgument);
}

TEST(Parameters, JsonRoundTripKeepsEverything) {
  MeshingParameters p;
  ASSERT_TRUE(setParameter(p, "target_edge_length", "0.75").isOk());
  ASSERT_TRUE(setParameter(p, "min_voxels", "3").isOk());
  ASSERT_TRUE(setParameter(p, "material.2.E", "17000").isOk());
  ASSERT_TRUE(setParameter(p, "material.2.nu", "0.25").isOk());
  auto q = parametersFromJson(parametersToJson(p));
  ASSERT_TRUE(q.isOk()) << q.status().message();
  EXPECT_EQ(parametersToJson(q.value()), parametersToJson(p));
  EXPECT_DOUBLE_EQ(q->materialProperties.at(2).youngsModulus, 17000);
  EXPECT_FALSE(parametersFromJson("{not json").isOk());
  EXPECT_FALSE(parametersFromJson("{\"bogus\": 1}").isOk());
}

TEST(Parameters, UserDefaultsAreTheStageDefaults) {
  // One source of truth: a default-constructed MeshingParameters holds each stage's own
  // defaults, and the descriptors report them.
  const MeshingParameters p;
  EXPECT_EQ(getParameter(p, "min_voxels"), "10");
  EXPECT_EQ(p.preprocess.minVoxels, LabelPreprocessParameters{}.minVoxels);
  EXPECT_EQ(getParameter(p, "smoothing_sigma"), "0.3");
  EXPECT_EQ(p.indicators.sigma, IndicatorParameters{}.sigma);
  EXPECT_EQ(getParameter(p, "sizing_scale"), "1.25");
  EXPECT_EQ(p.sizing.scale, SizingParameters{}.scale);
  EXPECT_EQ(getParameter(p, "particle_iterations"), "20");
  EXPECT_EQ(p.particles.maxIterations, ParticleSystemParameters{}.maxIterations);
  EXPECT_EQ(getParameter(p, "facet_distance"), "0.5");
  EXPECT_EQ(p.boundary.facetDistance, BoundaryMeshParameters{}.facetDistance);
  EXPECT_EQ(getParameter(p, "max_radius_edge_ratio"), "3");
  EXPECT_EQ(p.volume.maxRadiusEdgeRatio, VolumeMeshParameters{}.maxRadiusEdgeRatio);
  EXPECT_EQ(getParameter(p, "sliver_peel_distance"), "0.3");
  EXPECT_EQ(p.optimize.peelDistance, OptimizeParameters{}.peelDistance);
  EXPECT_EQ(getParameter(p, "sizing"), "adaptive");
  EXPECT_EQ(getParameter(p, "surface_mesher"), "delaunay");
}

TEST(Parameters, MaterialExclusionIsAParameterThatRoundTrips) {
  MeshingParameters p;
  ASSERT_TRUE(setParameter(p, "material.4.exclude", "merge").isOk());
  ASSERT_TRUE(setParameter(p, "material.7.exclude", "background").isOk());
  ASSERT_EQ(p.preprocess.excluded.size(), 2u);
  EXPECT_EQ(p.preprocess.excluded.at(4), Exclusion::MergeIntoNeighbour);
  EXPECT_EQ(p.preprocess.excluded.at(7), Exclusion::Background);
  Status bad = setParameter(p, "material.4.exclude", "maybe");
  EXPECT_EQ(bad.code(), ErrorCode::InvalidArgument);
  EXPECT_NE(bad.message().find("merge"), std::string::npos);
  auto q = parametersFromJson(parametersToJson(p));
  ASSERT_TRUE(q.isOk()) << q.status().message();
  EXPECT_EQ(q->preprocess.excluded, p.preprocess.excluded);
  EXPECT_EQ(parametersToJson(q.value()), parametersToJson(p));
  ASSERT_TRUE(setParameter(p, "material.4.exclude", "no").isOk());
  EXPECT_EQ(p.preprocess.excluded.count(4), 0u);
}

TEST(Parameters, MaterialNameIsAParameterThatRoundTrips) {
  MeshingParameters p;
  ASSERT_TRUE(setParameter(p, "material.3.name", "  femoral cartilage ").isOk());
  ASSERT_TRUE(setParameter(p, "material.9.name", "lesion \"A\", <1 mm>").isOk());
  EXPECT_EQ(p.preprocess.names.at(3), "femoral cartilage");  // trimmed
  EXPECT_TRUE(p.materialProperties.empty());                 // a name is not a property
  Status empty = setParameter(p, "material.3.name", "   ");
  EXPECT_EQ(empty.code(), ErrorCode::InvalidArgument);
  EXPECT_NE(empty.message().find("empty"), std::string::npos);
  EXPECT_EQ(setParameter(p, "material.3.name", "two\nlines").code(), ErrorCode::InvalidArgument);
  EXPECT_EQ(p.preprocess.names.at(3), "femoral cartilage");
  Status field = setParameter(p, "material.3.colour", "red");
  EXPECT_NE(field.message().find("name"), std::string::npos);  // lists the fields, name among them
  auto q = parametersFromJson(parametersToJson(p));
  ASSERT_TRUE(q.isOk()) << q.status().message();
  EXPECT_EQ(q->preprocess.names, p.preprocess.names);
  EXPECT_EQ(parametersToJson(q.value()), parametersToJson(p));
  EXPECT_FALSE(parametersFromJson("{\"materials\": {\"3\": {\"name\": 7}}}").isOk());
}

TEST(Parameters, PropertiesAndNamesOfAbsentLabelsAreRejected) {
  MeshingParameters p;
  EXPECT_TRUE(checkMaterialLabels(p, {1, 2}, "knee.nii.gz").isOk());
  ASSERT_TRUE(setParameter(p, "material.2.E", "17000").isOk());
  ASSERT_TRUE(setParameter(p, "material.2.name", "bone").isOk());
  ASSERT_TRUE(setParameter(p, "material.4.exclude", "background").isOk());  // only warned about
  EXPECT_TRUE(checkMaterialLabels(p, {1, 2}, "knee.nii.gz").isOk());
  ASSERT_TRUE(setParameter(p, "material.12.E", "5").isOk());
  ASSERT_TRUE(setParameter(p, "material.13.name", "screw").isOk());
  const Status s = checkMaterialLabels(p, {1, 2, 3}, "knee.nii.gz");
  ASSERT_EQ(s.code(), ErrorCode::InvalidArgument);
  for (const char* part : {"'knee.nii.gz'", "no label 12, 13", "material.12.E", "material.13.name",
                           "labels 1, 2, 3", "femesher info"})
    EXPECT_NE(s.message().find(part), std::string::npos) << part << " in: " << s.message();
}

TEST(Parameters, PresetsDifferInSize) {
  auto c = presetParameters("coarse"), f = presetParameters("fine");
  ASSERT_TRUE(c.isOk() && f.isOk());
  EXPECT_GT(c->sizing.edgeLengthFactor, f->sizing.edgeLengthFactor);
  EXPECT_FALSE(presetParameters("ultra").isOk());
}

TEST(RunContext, WeightedProgressIsMonotoneAndCancelThrows) {
  RunContext ctx;
  std::vector<double> totals;
  ctx.setProgressCallback([&](const std::string&, double, double t) { totals.push_back(t); });
  ctx.setStagePlan({{"a", 1}, {"b", 3}});
  ctx.beginStage("a");
  ctx.endStage();
  ctx.beginStage("b");
  ctx.progress(0.5);
  ctx.endStage();
  ASSERT_FALSE(totals.empty());
  for (size_t i = 1; i < totals.size(); ++i) EXPECT_GE(totals[i], totals[i - 1]);
  EXPECT_NEAR(totals.back(), 1.0, 1e-12);
  std::thread t([&] { ctx.cancel(); });
  t.join();
  EXPECT_THROW(ctx.checkCancel(), Error);
}

TEST(Types, PhysicalCanonicalRoundTripObliqueLeftHanded) {
  LabelVolume v;
  v.dims = {4, 5, 6};
  v.spacing = {0.7, 0.36, 0.36};
  v.origin = {-24, 51.8, -57.1};
  // a rotation about z composed with a flip of x (det = -1)
  const double c = 0.978, s = 0.208;
  v.direction = {-c, s, 0, -s, -c, 0, 0, 0, -1};
  EXPECT_LT(v.directionDeterminant(), 0);
  const Vec3 ijk{1.5, 2.25, 3};
  const Vec3 p = v.indexToPhysical(ijk);
  const Vec3 back = v.physicalToIndex(p);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(back[a], ijk[a], 1e-12);
}

TEST(Types, ExtractInterfacesOfTwoTets) {
  TetMesh m;
  m.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, -1}};
  m.tets = {{0, 1, 2, 3}, {0, 2, 1, 4}};
  m.tetLabels = {1, 2};
  ASSERT_GT(m.tetVolume(0), 0);
  ASSERT_GT(m.tetVolume(1), 0);
  auto faces = extractInterfaces(m);
  // 3 + 3 boundary faces and one shared face between labels 1 and 2.
  ASSERT_EQ(faces.size(), 7u);
  int shared = 0;
  for (const auto& f : faces)
    if (f.labelB != kExteriorLabel) {
      ++shared;
      EXPECT_EQ(f.labelA, 1);
      EXPECT_EQ(f.labelB, 2);
    }
  EXPECT_EQ(shared, 1);
  m.tetLabels = {1, 1};
  EXPECT_EQ(extractInterfaces(m).size(), 6u);
}

TEST(StageTable, PipelineKeysAreUniqueAndTitled) {
  std::set<std::string> keys;
  for (const auto& s : stageTable()) {
    EXPECT_TRUE(keys.insert(s.key).second) << s.key;
    EXPECT_GT(std::string(s.title).size(), 5u) << s.key;
    EXPECT_GT(s.weight, 0) << s.key;
    EXPECT_EQ(&stageInfo(s.id), &s);
    EXPECT_EQ(findStage(s.key), &s);
  }
  EXPECT_EQ(findStage("NoSuchStage"), nullptr);
}
