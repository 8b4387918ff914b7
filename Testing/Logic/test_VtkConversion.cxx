// SPDX-License-Identifier: GPL-3.0-or-later
// The VTK adapter (io/VtkConversion.h): TetMesh <-> vtkUnstructuredGrid in LPS and RAS, the
// `labels` cell array and the field data the .vtu writer stores, errors of the grid -> mesh
// direction, and label maps from a VTK image with an oblique IJK -> RAS matrix (the 3D Slicer
// path), checked as label-map files are.
#include <femesher/Version.h>
#include <femesher/io/MeshIO.h>
#include <femesher/io/VtkConversion.h>
#include <gtest/gtest.h>
#include <vtkCellData.h>
#include <vtkDoubleArray.h>
#include <vtkFieldData.h>
#include <vtkFloatArray.h>
#include <vtkIdList.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStringArray.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnsignedShortArray.h>
#include <vtkUnstructuredGrid.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

using namespace femesher;

namespace {

/// Two tets sharing a face, oblique non-round coordinates (as a mesh of an oblique, left-handed
/// volume has), labels 7 (named) and -2 (unnamed: no material entry).
TetMesh obliqueMesh() {
  TetMesh m;
  m.points = {{-12.345678901234567, 51.79960000000001, -57.13971},
              {-11.2, 52.30000000000003, -57.0},
              {-12.1, 53.1, -56.2},
              {-13.0, 52.2, -55.9},
              {-10.9, 53.7, -55.1}};
  m.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  for (size_t t = 0; t < m.tets.size(); ++t)
    if (m.tetVolume(t) < 0) std::swap(m.tets[t][2], m.tets[t][3]);
  m.tetLabels = {7, -2};
  m.materials = {{7, "cortical bone", {0.9, 0.8, 0.7}}};
  return m;
}

/// The strings of a text field array (UInt8: UTF-8 bytes, each string followed by a 0 byte).
std::vector<std::string> textValues(vtkFieldData* fd, const char* name) {
  auto* a = vtkUnsignedCharArray::SafeDownCast(fd->GetAbstractArray(name));
  if (!a) return {"<missing>"};
  std::vector<std::string> out(1);
  for (vtkIdType k = 0; k < a->GetNumberOfValues(); ++k) {
    if (a->GetValue(k) == 0) out.emplace_back();
    else out.back() += char(a->GetValue(k));
  }
  if (!out.back().empty()) return {"<not 0-terminated>"};
  out.pop_back();
  return out;
}

std::string textValue(vtkFieldData* fd, const char* name) {
  const auto v = textValues(fd, name);
  return v.size() == 1 ? v[0] : std::string("<not one string>");
}

/// Fills the top three rows of `m`; the last row stays 0 0 0 1.
void setRows(vtkMatrix4x4* m, const double rows[3][4]) {
  m->Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m->SetElement(r, c, rows[r][c]);
}

/// An oblique IJK -> RAS matrix: rotation about an oblique axis times spacing (0.5, 0.8, 1.2).
void obliqueIjkToRas(vtkMatrix4x4* m) {
  const double a = 0.4, ca = std::cos(a), sa = std::sin(a);
  const double rot[3][3] = {{ca, -sa, 0}, {sa * 0.6, ca * 0.6, -0.8}, {sa * 0.8, ca * 0.8, 0.6}};
  const double spacing[3] = {0.5, 0.8, 1.2}, origin[3] = {10.25, -20.5, 30.125};
  double rows[3][4];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rows[r][c] = rot[r][c] * spacing[c];
    rows[r][3] = origin[r];
  }
  setRows(m, rows);
}

/// A 4 x 3 x 2 image with extent starting at (2, 1, 5); scalars from `value(i, j, k)`.
template <class Array, class Fn>
vtkNew<vtkImageData> makeImage(Fn value, int components = 1) {
  vtkNew<vtkImageData> image;
  image->SetExtent(2, 5, 1, 3, 5, 6);
  vtkNew<Array> scalars;
  scalars->SetNumberOfComponents(components);
  scalars->SetNumberOfTuples(4 * 3 * 2);
  vtkIdType n = 0;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i, ++n)
        for (int c = 0; c < components; ++c) scalars->SetComponent(n, c, value(i, j, k));
  image->GetPointData()->SetScalars(scalars);
  return image;
}

}  // namespace

TEST(VtkConversion, MeshToGridKeepsPointsTetsAndLabelsBitForBit) {
  const TetMesh m = obliqueMesh();
  vtkNew<vtkUnstructuredGrid> grid;
  meshToVtkGrid(m, grid);
  ASSERT_EQ(grid->GetNumberOfPoints(), 5);
  EXPECT_EQ(grid->GetPoints()->GetDataType(), VTK_DOUBLE);
  for (vtkIdType i = 0; i < 5; ++i) {
    double p[3];
    grid->GetPoint(i, p);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(p[k], m.points[size_t(i)][k]) << "point " << i;
  }
  ASSERT_EQ(grid->GetNumberOfCells(), 2);
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < 2; ++c) {
    EXPECT_EQ(grid->GetCellType(c), VTK_TETRA);
    grid->GetCellPoints(c, ids);
    ASSERT_EQ(ids->GetNumberOfIds(), 4);
    for (int k = 0; k < 4; ++k) EXPECT_EQ(ids->GetId(k), m.tets[size_t(c)][size_t(k)]);
  }
  auto* labels = vtkIntArray::SafeDownCast(grid->GetCellData()->GetArray("labels"));
  ASSERT_NE(labels, nullptr);
  EXPECT_EQ(labels->GetValue(0), 7);
  EXPECT_EQ(labels->GetValue(1), -2);
  EXPECT_EQ(grid->GetCellData()->GetScalars(), labels);
  EXPECT_EQ(grid->GetFieldData()->GetNumberOfArrays(), 0) << "field data only when asked for";
}

TEST(VtkConversion, FieldDataIsWhatTheVtuWriterStores) {
  const TetMesh m = obliqueMesh();
  vtkNew<vtkUnstructuredGrid> grid;
  VtkGridOptions options;
  options.fieldData = true;
  options.provenance = "femesher test";
  meshToVtkGrid(m, grid, options);
  vtkFieldData* fd = grid->GetFieldData();
  // Only numeric arrays (meshio cannot parse VTK's string arrays), hence no SPACE tag (Slicer
  // reads it only as a string array and takes a file without one as LPS).
  EXPECT_EQ(fd->GetAbstractArray("SPACE"), nullptr);
  for (int a = 0; a < fd->GetNumberOfArrays(); ++a)
    EXPECT_NE(vtkDataArray::SafeDownCast(fd->GetAbstractArray(a)), nullptr)
        << fd->GetAbstractArray(a)->GetName() << " is not a numeric array";
  EXPECT_EQ(textValue(fd, "FEMesherVersion"), FEMESHER_VERSION);
  EXPECT_EQ(textValue(fd, "Provenance"), "femesher test");
  auto* ids = vtkIntArray::SafeDownCast(fd->GetAbstractArray("MaterialIds"));
  auto* colors = vtkDoubleArray::SafeDownCast(fd->GetAbstractArray("MaterialColors"));
  ASSERT_TRUE(ids && colors);
  ASSERT_EQ(ids->GetNumberOfValues(), 2);  // ascending: -2, 7
  EXPECT_EQ(ids->GetValue(0), -2);
  EXPECT_EQ(ids->GetValue(1), 7);
  EXPECT_EQ(textValues(fd, "MaterialNames"),
            (std::vector<std::string>{"label -2", "cortical bone"}));
  ASSERT_EQ(colors->GetNumberOfComponents(), 3);
  EXPECT_EQ(colors->GetComponent(1, 0), 0.9);
  EXPECT_EQ(colors->GetComponent(0, 2), defaultLabelColor(-2)[2]);
  // Without provenance there is no Provenance array.
  options.provenance.clear();
  meshToVtkGrid(m, grid, options);
  EXPECT_EQ(grid->GetFieldData()->GetAbstractArray("Provenance"), nullptr);
  EXPECT_EQ(grid->GetFieldData()->GetNumberOfArrays(), 4);
}

TEST(VtkConversion, GridIsResetBeforeItIsFilled) {
  // The GUI view refills one grid for every new mesh.
  vtkNew<vtkUnstructuredGrid> grid;
  VtkGridOptions withFieldData;
  withFieldData.fieldData = true;
  TetMesh big = obliqueMesh();
  meshToVtkGrid(big, grid, withFieldData);
  grid->GetCellData()->AddArray(vtkNew<vtkDoubleArray>().GetPointer());
  TetMesh small = big;
  small.tets.pop_back();
  small.tetLabels.pop_back();
  meshToVtkGrid(small, grid);
  EXPECT_EQ(grid->GetNumberOfCells(), 1);
  EXPECT_EQ(grid->GetCellData()->GetNumberOfArrays(), 1);
  EXPECT_EQ(grid->GetFieldData()->GetNumberOfArrays(), 0);
}

TEST(VtkConversion, RasFrameNegatesXAndYAndKeepsTetOrientation) {
  const TetMesh m = obliqueMesh();
  vtkNew<vtkUnstructuredGrid> grid;
  VtkGridOptions options;
  options.frame = VtkFrame::RAS;
  options.fieldData = true;
  meshToVtkGrid(m, grid, options);
  EXPECT_EQ(grid->GetFieldData()->GetAbstractArray("SPACE"), nullptr);
  double p[3];
  grid->GetPoint(0, p);
  EXPECT_EQ(p[0], -m.points[0][0]);
  EXPECT_EQ(p[1], -m.points[0][1]);
  EXPECT_EQ(p[2], m.points[0][2]);
  // Read back as RAS: the LPS mesh again, tets still positive.
  auto back = vtkGridToMesh(grid, "ras grid", VtkFrame::RAS);
  ASSERT_TRUE(back.isOk()) << back.status().message();
  EXPECT_EQ(back->points, m.points);
  EXPECT_EQ(back->tets, m.tets);
  for (size_t t = 0; t < back->tets.size(); ++t) EXPECT_GT(back->tetVolume(t), 0);
  // Read as if it were LPS: mirrored twice over, i.e. x and y negated.
  auto asLps = vtkGridToMesh(grid, "ras grid");
  ASSERT_TRUE(asLps.isOk());
  EXPECT_EQ(asLps->points[0][0], -m.points[0][0]);
}

TEST(VtkConversion, RoundTripKeepsMeshAndMaterialTable) {
  const TetMesh m = obliqueMesh();
  vtkNew<vtkUnstructuredGrid> grid;
  VtkGridOptions options;
  options.fieldData = true;
  meshToVtkGrid(m, grid, options);
  auto back = vtkGridToMesh(grid, "memory");
  ASSERT_TRUE(back.isOk()) << back.status().message();
  EXPECT_EQ(back->points, m.points);  // bit for bit: LPS coordinates are not touched
  EXPECT_EQ(back->tets, m.tets);
  EXPECT_EQ(back->tetLabels, m.tetLabels);
  ASSERT_EQ(back->materials.size(), 2u);
  EXPECT_EQ(back->materials[0].id, -2);
  EXPECT_EQ(back->materials[0].name, "label -2");
  EXPECT_EQ(back->materials[1].name, "cortical bone");
  EXPECT_EQ(back->materials[1].color, m.materials[0].color);
  // Files written before 0-terminated UInt8 text held the names in a vtkStringArray: still read.
  {
    vtkNew<vtkStringArray> oldNames;
    oldNames->SetName("MaterialNames");
    oldNames->InsertNextValue("old -2");
    oldNames->InsertNextValue("old 7");
    grid->GetFieldData()->RemoveArray("MaterialNames");
    grid->GetFieldData()->AddArray(oldNames);
    auto fromOld = vtkGridToMesh(grid, "memory");
    ASSERT_TRUE(fromOld.isOk()) << fromOld.status().message();
    EXPECT_EQ(fromOld->materials[0].name, "old -2");
    EXPECT_EQ(fromOld->materials[1].name, "old 7");
  }
  // Without field data: default names and colours.
  meshToVtkGrid(m, grid);
  back = vtkGridToMesh(grid, "memory");
  ASSERT_TRUE(back.isOk());
  EXPECT_EQ(back->materials[1].name, "label 7");
  EXPECT_EQ(back->materials[1].color, defaultLabelColor(7));
}

TEST(VtkConversion, VtuFileHoldsTheConvertedGrid) {
  // The .vtu writer and reader go through the adapter: the file round trip is bit-exact too.
  const TetMesh m = obliqueMesh();
  const std::string dir = std::string(FEMESHER_TEST_TMP_DIR) + "/VtkConversion";
  std::filesystem::create_directories(dir);
  ExportOptions o;
  o.provenance = "round trip";
  ASSERT_TRUE(writeMesh(m, dir + "/oblique.vtu", o).isOk());
  auto back = readMesh(dir + "/oblique.vtu");
  ASSERT_TRUE(back.isOk()) << back.status().message();
  EXPECT_EQ(back->points, m.points);
  EXPECT_EQ(back->tets, m.tets);
  EXPECT_EQ(back->tetLabels, m.tetLabels);
  EXPECT_EQ(back->materials[1].name, "cortical bone");
}

TEST(VtkConversion, GridToMeshErrorsNameTheSource) {
  auto expectError = [](vtkUnstructuredGrid* g, ErrorCode code, const char* what) {
    auto r = vtkGridToMesh(g, "src.vtu");
    ASSERT_FALSE(r.isOk()) << what;
    EXPECT_EQ(r.status().code(), code) << what << ": " << r.status().message();
    EXPECT_NE(r.status().message().find("'src.vtu'"), std::string::npos) << r.status().message();
  };
  vtkNew<vtkUnstructuredGrid> empty;
  expectError(empty, ErrorCode::CorruptFile, "no cells");
  expectError(nullptr, ErrorCode::CorruptFile, "null grid");

  const TetMesh m = obliqueMesh();
  vtkNew<vtkUnstructuredGrid> grid;
  meshToVtkGrid(m, grid);
  grid->GetCellData()->RemoveArray("labels");
  expectError(grid, ErrorCode::UnreadableFile, "no labels");

  meshToVtkGrid(m, grid);
  vtkNew<vtkDoubleArray> fractional;
  fractional->SetName("labels");
  fractional->SetNumberOfValues(2);
  fractional->SetValue(0, 1);
  fractional->SetValue(1, 1.5);
  grid->GetCellData()->RemoveArray("labels");
  grid->GetCellData()->AddArray(fractional);
  expectError(grid, ErrorCode::CorruptFile, "non-integer label");

  meshToVtkGrid(m, grid);
  const vtkIdType tri[3] = {0, 1, 2};
  grid->InsertNextCell(VTK_TRIANGLE, 3, tri);
  grid->GetCellData()->GetArray("labels")->InsertNextTuple1(7);
  expectError(grid, ErrorCode::UnreadableFile, "triangle cell");

  meshToVtkGrid(m, grid);
  const vtkIdType outside[4] = {0, 1, 2, 99};
  grid->InsertNextCell(VTK_TETRA, 4, outside);
  grid->GetCellData()->GetArray("labels")->InsertNextTuple1(7);
  expectError(grid, ErrorCode::CorruptFile, "vertex index out of range");
}

TEST(VtkConversion, ImageWithObliqueRasMatrixGivesLpsGeometry) {
  auto label = [](int i, int j, int k) {
    return (i + 2 * j + k) % 3 == 0 ? 0 : 1 + (i + j + k) % 2 * 40;
  };
  auto image = makeImage<vtkUnsignedShortArray>(label);
  vtkNew<vtkMatrix4x4> ijkToRas;
  obliqueIjkToRas(ijkToRas);
  auto r = labelVolumeFromVtkImage(image, ijkToRas, VtkFrame::RAS, "Segment_1");
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const LabelVolume& v = r.value();
  EXPECT_EQ(v.dims, (std::array<int, 3>{4, 3, 2}));
  EXPECT_EQ(v.sourcePath, "Segment_1");
  EXPECT_NEAR(v.spacing[0], 0.5, 1e-12);
  EXPECT_NEAR(v.spacing[1], 0.8, 1e-12);
  EXPECT_NEAR(v.spacing[2], 1.2, 1e-12);
  EXPECT_NEAR(std::fabs(v.directionDeterminant()), 1.0, 1e-12);
  // Every voxel centre: FEMesher's LPS position = the matrix's RAS position with x, y negated.
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i) {
        const double ijk[4] = {double(i + 2), double(j + 1), double(k + 5), 1.0};
        double ras[4];
        ijkToRas->MultiplyPoint(ijk, ras);
        const Vec3 p = v.indexToPhysical({double(i), double(j), double(k)});
        EXPECT_NEAR(p[0], -ras[0], 1e-9);
        EXPECT_NEAR(p[1], -ras[1], 1e-9);
        EXPECT_NEAR(p[2], ras[2], 1e-9);
        EXPECT_EQ(v.at(i, j, k), label(i, j, k));
      }
  ASSERT_EQ(v.materials.size(), 2u);
  EXPECT_EQ(v.materials[0].id, 1);
  EXPECT_EQ(v.materials[1].id, 41);
  EXPECT_EQ(v.materials[1].name, "label 41");
  EXPECT_EQ(v.materials[1].color, defaultLabelColor(41));
  // The same matrix read as LPS keeps the coordinates as they are.
  auto lps = labelVolumeFromVtkImage(image, ijkToRas, VtkFrame::LPS, "lps");
  ASSERT_TRUE(lps.isOk());
  EXPECT_EQ(lps->origin[0], ijkToRas->GetElement(0, 0) * 2 + ijkToRas->GetElement(0, 1) * 1 +
                                ijkToRas->GetElement(0, 2) * 5 + ijkToRas->GetElement(0, 3));
}

TEST(VtkConversion, ImageIsCheckedLikeALabelMapFile) {
  vtkNew<vtkMatrix4x4> ijkToRas;
  obliqueIjkToRas(ijkToRas);
  auto expectError = [&](vtkImageData* image, vtkMatrix4x4* m, ErrorCode code, const char* what) {
    auto r = labelVolumeFromVtkImage(image, m, VtkFrame::RAS, "node A");
    ASSERT_FALSE(r.isOk()) << what;
    EXPECT_EQ(r.status().code(), code) << what << ": " << r.status().message();
    EXPECT_EQ(r.status().message().rfind("'node A'", 0), 0u) << r.status().message();
  };
  expectError(nullptr, ijkToRas, ErrorCode::InvalidArgument, "no image");
  auto ct = makeImage<vtkFloatArray>([](int i, int j, int k) { return 0.5 * (i + j + k); });
  expectError(ct, ijkToRas, ErrorCode::NotALabelMap, "non-integer floats");
  auto zeros = makeImage<vtkUnsignedShortArray>([](int, int, int) { return 0; });
  expectError(zeros, ijkToRas, ErrorCode::EmptyLabelMap, "only background");
  auto rgb = makeImage<vtkUnsignedShortArray>([](int, int, int) { return 1; }, 3);
  expectError(rgb, ijkToRas, ErrorCode::InvalidArgument, "three components");
  auto ones = makeImage<vtkUnsignedShortArray>([](int, int, int) { return 1; });
  expectError(ones, nullptr, ErrorCode::InvalidArgument, "no matrix");
  vtkNew<vtkMatrix4x4> flat;
  flat->SetElement(2, 2, 0);  // the k axis has no length
  expectError(ones, flat, ErrorCode::CorruptFile, "zero spacing");

  // More than 65,535 labels: the intensity image the 3D Slicer module used to let through.
  vtkNew<vtkImageData> many;
  many->SetDimensions(300, 300, 1);
  vtkNew<vtkIntArray> values;
  values->SetNumberOfValues(300 * 300);
  for (vtkIdType i = 0; i < 300 * 300; ++i) values->SetValue(i, int(i) + 1);
  many->GetPointData()->SetScalars(values);
  expectError(many, ijkToRas, ErrorCode::TooManyLabels, "90,000 labels");
}
