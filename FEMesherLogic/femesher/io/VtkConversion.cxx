// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/VecMath.h>
#include <femesher/Version.h>
#include <femesher/io/LabelValidation.h>
#include <femesher/io/MeshFormats.h>
#include <femesher/io/QuadraticTets.h>
#include <femesher/io/VtkConversion.h>
#include <vtkCellData.h>
#include <vtkDoubleArray.h>
#include <vtkFieldData.h>
#include <vtkIdList.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStringArray.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>

#include <cmath>
#include <string>
#include <vector>

namespace femesher {

namespace {

using meshio::fail;

/// LPS <-> RAS (its own inverse); identity when the frame is LPS.
Vec3 toFrame(const Vec3& p, VtkFrame frame) {
  return frame == VtkFrame::RAS ? Vec3{{-p[0], -p[1], p[2]}} : p;
}

/// Text as a UInt8 field array: the UTF-8 bytes of each string, each followed by a 0 byte.
/// VTK's text arrays (vtkStringArray) are avoided on purpose: meshio cannot read them.
void addText(vtkFieldData* fd, const char* name, const std::vector<std::string>& strings) {
  vtkNew<vtkUnsignedCharArray> a;
  a->SetName(name);
  for (const auto& s : strings) {
    for (char c : s) a->InsertNextValue(static_cast<unsigned char>(c));
    a->InsertNextValue(0);
  }
  fd->AddArray(a);
}

/// The strings of a field array written by `addText`; empty when there is none.
std::vector<std::string> readText(vtkFieldData* fd, const char* name) {
  std::vector<std::string> out;
  auto* a = vtkUnsignedCharArray::SafeDownCast(fd ? fd->GetAbstractArray(name) : nullptr);
  if (!a || a->GetNumberOfComponents() != 1) return out;
  std::string cur;
  for (vtkIdType k = 0; k < a->GetNumberOfValues(); ++k) {
    const unsigned char c = a->GetValue(k);
    if (c == 0) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += static_cast<char>(c);
    }
  }
  return out;
}

void addFieldData(const TetMesh& m, const VtkGridOptions& o, vtkFieldData* fd) {
  vtkNew<vtkIntArray> ids;
  ids->SetName("MaterialIds");
  std::vector<std::string> names;
  vtkNew<vtkDoubleArray> colors;
  colors->SetName("MaterialColors");
  colors->SetNumberOfComponents(3);
  for (int32_t l : meshio::meshLabels(m)) {
    const Material* mat = findMaterial(m.materials, l);
    ids->InsertNextValue(l);
    names.push_back(meshio::materialName(m, l));
    const auto c = mat ? mat->color : defaultLabelColor(l);
    colors->InsertNextTuple(c.data());
  }
  fd->AddArray(ids);
  addText(fd, "MaterialNames", names);
  fd->AddArray(colors);
  addText(fd, "FEMesherVersion", {FEMESHER_VERSION});
  if (!o.provenance.empty()) addText(fd, "Provenance", {o.provenance});
}

/// Material names and colours from the field data written by `addFieldData`.
void readFieldData(vtkFieldData* fd, std::map<int32_t, std::string>& names,
                   std::map<int32_t, std::array<double, 3>>& colors) {
  auto* idArr = vtkIntArray::SafeDownCast(fd ? fd->GetAbstractArray("MaterialIds") : nullptr);
  // Names: UInt8 text (addText); files of earlier versions hold a vtkStringArray.
  std::vector<std::string> nameList = readText(fd, "MaterialNames");
  auto* old = vtkStringArray::SafeDownCast(fd ? fd->GetAbstractArray("MaterialNames") : nullptr);
  if (old)
    for (vtkIdType k = 0; k < old->GetNumberOfValues(); ++k) nameList.push_back(old->GetValue(k));
  auto* colorArr =
      vtkDataArray::SafeDownCast(fd ? fd->GetAbstractArray("MaterialColors") : nullptr);
  if (!idArr) return;
  for (vtkIdType k = 0; k < idArr->GetNumberOfValues(); ++k) {
    if (size_t(k) < nameList.size()) names[idArr->GetValue(k)] = nameList[size_t(k)];
    if (colorArr && colorArr->GetNumberOfComponents() == 3 && k < colorArr->GetNumberOfTuples()) {
      double c[3];
      colorArr->GetTuple(k, c);
      colors[idArr->GetValue(k)] = {c[0], c[1], c[2]};
    }
  }
}

/// Spacing, direction and origin from an IJK -> `frame` matrix; `extent` as vtkImageData's.
void setGeometry(const vtkMatrix4x4& ijkToWorld, const int extent[6], VtkFrame frame,
                 LabelVolume& v) {
  for (int c = 0; c < 3; ++c) {
    v.dims[c] = extent[2 * c + 1] - extent[2 * c] + 1;
    const Vec3 column = toFrame(
        {ijkToWorld.GetElement(0, c), ijkToWorld.GetElement(1, c), ijkToWorld.GetElement(2, c)},
        frame);
    v.spacing[c] = norm(column);
    for (int r = 0; r < 3; ++r)
      v.direction[3 * r + c] = v.spacing[c] > 0 ? column[r] / v.spacing[c] : 0.0;
  }
  Vec3 first;
  for (int r = 0; r < 3; ++r)
    first[r] = ijkToWorld.GetElement(r, 0) * extent[0] + ijkToWorld.GetElement(r, 1) * extent[2] +
               ijkToWorld.GetElement(r, 2) * extent[4] + ijkToWorld.GetElement(r, 3);
  v.origin = toFrame(first, frame);
}

}  // namespace

void meshToVtkGrid(const TetMesh& m, vtkUnstructuredGrid* ug, const VtkGridOptions& o) {
  ug->Initialize();
  const bool quadratic = o.elementOrder == 2;
  const QuadraticTetMesh q = quadratic ? quadraticTets(m, o.midEdgeNodes) : QuadraticTetMesh{};
  const std::vector<Vec3>& points = quadratic ? q.points : m.points;
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(vtkIdType(points.size()));
  for (size_t i = 0; i < points.size(); ++i)
    pts->SetPoint(vtkIdType(i), toFrame(points[i], o.frame).data());
  ug->SetPoints(pts);
  ug->Allocate(vtkIdType(m.tets.size()));
  for (size_t t = 0; t < m.tets.size(); ++t) {
    if (quadratic) {
      vtkIdType ids[10];
      for (size_t k = 0; k < 10; ++k) ids[k] = q.tets[t][k];
      ug->InsertNextCell(VTK_QUADRATIC_TETRA, 10, ids);
    } else {
      const auto& v = m.tets[t];
      const vtkIdType ids[4] = {v[0], v[1], v[2], v[3]};
      ug->InsertNextCell(VTK_TETRA, 4, ids);
    }
  }
  vtkNew<vtkIntArray> labels;
  labels->SetName("labels");
  labels->SetNumberOfValues(vtkIdType(m.tetLabels.size()));
  for (size_t i = 0; i < m.tetLabels.size(); ++i) labels->SetValue(vtkIdType(i), m.tetLabels[i]);
  ug->GetCellData()->AddArray(labels);
  ug->GetCellData()->SetActiveScalars("labels");
  if (o.fieldData) addFieldData(m, o, ug->GetFieldData());
}

Result<TetMesh> vtkGridToMesh(vtkUnstructuredGrid* ug, const std::string& path, VtkFrame frame,
                              std::vector<std::array<int32_t, 6>>* midNodes) {
  if (!ug || ug->GetNumberOfCells() == 0)
    return fail(ErrorCode::CorruptFile, path, "it holds no cells.");
  vtkDataArray* labels = ug->GetCellData()->GetArray("labels");
  if (!labels || labels->GetNumberOfTuples() != ug->GetNumberOfCells())
    return fail(ErrorCode::UnreadableFile, path,
                "it has no cell array 'labels' with one material id per cell (not a labelled mesh; "
                "write it with FEMesher or add an integer cell array named 'labels').");
  TetMesh m;
  m.points.resize(size_t(ug->GetNumberOfPoints()));
  for (vtkIdType i = 0; i < ug->GetNumberOfPoints(); ++i) {
    ug->GetPoint(i, m.points[size_t(i)].data());
    m.points[size_t(i)] = toFrame(m.points[size_t(i)], frame);
  }
  m.tets.reserve(size_t(ug->GetNumberOfCells()));
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < ug->GetNumberOfCells(); ++c) {
    const int type = ug->GetCellType(c);
    if (type != VTK_TETRA && !(type == VTK_QUADRATIC_TETRA && midNodes))
      return fail(ErrorCode::UnreadableFile, path,
                  "cell " + std::to_string(c) + " is not a linear" +
                      (midNodes ? " or 10-node" : "") + " tetrahedron (VTK type " +
                      std::to_string(type) + ").");
    ug->GetCellPoints(c, ids);
    if (midNodes) {
      std::array<int32_t, 6> mid{{-1, -1, -1, -1, -1, -1}};
      if (type == VTK_QUADRATIC_TETRA)  // vtkQuadraticTetra's order is kTet10Edges'
        for (size_t k = 0; k < 6; ++k) mid[k] = int32_t(ids->GetId(vtkIdType(4 + k)));
      midNodes->push_back(mid);
    }
    m.tets.push_back({int32_t(ids->GetId(0)), int32_t(ids->GetId(1)), int32_t(ids->GetId(2)),
                      int32_t(ids->GetId(3))});
    const double v = labels->GetTuple1(c);
    if (v != std::floor(v) || std::fabs(v) > 2147483647.0)
      return fail(ErrorCode::CorruptFile, path, "cell array 'labels' holds a non-integer value.");
    m.tetLabels.push_back(int32_t(v));
  }
  std::map<int32_t, std::string> names;
  std::map<int32_t, std::array<double, 3>> colors;
  readFieldData(ug->GetFieldData(), names, colors);
  return meshio::finishRead(std::move(m), path, names, colors);
}

Result<LabelVolume> labelVolumeFromVtkImage(vtkImageData* image, const vtkMatrix4x4* ijkToWorld,
                                            VtkFrame frame, const std::string& source) {
  using R = Result<LabelVolume>;
  const std::string name = "'" + source + "'";
  vtkDataArray* scalars =
      image && image->GetPointData() ? image->GetPointData()->GetScalars() : nullptr;
  if (!scalars || !ijkToWorld)
    return R(ErrorCode::InvalidArgument, name + " has no image data or no voxel-to-world matrix.");
  if (scalars->GetNumberOfComponents() != 1)
    return R(ErrorCode::InvalidArgument,
             name + " has " + std::to_string(scalars->GetNumberOfComponents()) +
                 " values per voxel; FEMesher needs one integer label per voxel.");
  VoxelType type = VoxelType::Int32;
  switch (scalars->GetDataType()) {
    vtkTemplateMacro(type = voxelTypeOf<VTK_TT>());
    default:
      return R(ErrorCode::InvalidArgument, name + " has an unsupported scalar type (" +
                                               scalars->GetDataTypeAsString() +
                                               "); use integer voxels.");
  }
  int extent[6];
  image->GetExtent(extent);
  LabelVolume v;
  v.sourcePath = source;
  setGeometry(*ijkToWorld, extent, frame, v);
  if (Status s = validateLabelGeometry(v, source); !s) return s;
  if (size_t(scalars->GetNumberOfTuples()) != v.voxelCount())
    return R(ErrorCode::InvalidArgument,
             name + " has " + std::to_string(scalars->GetNumberOfTuples()) + " values for " +
                 std::to_string(v.voxelCount()) + " voxels.");
  auto labels = labelsFromVoxels(scalars->GetVoidPointer(0), type, v.voxelCount(), source);
  if (!labels) return labels.status();
  v.labels = std::move(labels).value();
  const auto present = validateLabelVolume(v, source);
  if (!present) return present.status();
  v.materials = defaultMaterials(present.value());
  return v;
}

}  // namespace femesher
