// SPDX-License-Identifier: GPL-3.0-or-later
#include "qFEMesherPreviewView.h"

#include <femesher/io/VtkConversion.h>

#include <QVTKOpenGLNativeWidget.h>

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataSetSurfaceFilter.h>
#include <vtkDoubleArray.h>
#include <vtkExtractGeometry.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkLegendBoxActor.h>
#include <vtkLookupTable.h>
#include <vtkOutlineSource.h>
#include <vtkPlane.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSphereSource.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkWindowToImageFilter.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkAxesActor.h>
#include <vtkCaptionActor2D.h>
#include <vtkDiscreteFlyingEdges3D.h>
#include <vtkOrientationMarkerWidget.h>
#include <vtkRenderWindowInteractor.h>

#include <QCheckBox>
#include <QComboBox>
#include <QDateTime>
#include <QHBoxLayout>
#include <QLabel>
#include <QSlider>
#include <QThread>
#include <QTimer>
#include <QVBoxLayout>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace {

/// Well-separated colours for interface pairs (assigned in order of first appearance).
const double kPairPalette[][3] = {
    {0.89, 0.10, 0.11}, {0.22, 0.49, 0.72}, {0.30, 0.69, 0.29}, {0.60, 0.31, 0.64},
    {1.00, 0.50, 0.00}, {0.65, 0.34, 0.16}, {0.97, 0.51, 0.75}, {0.10, 0.75, 0.80},
    {0.74, 0.74, 0.13}, {0.92, 0.92, 0.92}, {0.55, 0.83, 0.78}, {0.98, 0.75, 0.43},
    {0.50, 0.69, 0.83}, {0.80, 0.92, 0.77}, {0.70, 0.55, 0.95}, {0.85, 0.37, 0.01}};
constexpr int kPairPaletteSize = sizeof(kPairPalette) / sizeof(kPairPalette[0]);

const char* kColorByNames[] = {"Material", "Aspect ratio", "Radius ratio",
                               "Min dihedral angle", "Scaled Jacobian"};

/// What a worker builds for a large mesh: its boundary and interface triangles (points compacted
/// to the ones used, cell array "labels" = the side the triangle is coloured by) and the per-tet
/// quality for metric colouring.
struct SurfaceJob {
  std::shared_ptr<const femesher::TetMesh> mesh;
  vtkSmartPointer<vtkPolyData> poly;
  std::vector<std::array<int32_t, 2>> cellTets;
  std::unique_ptr<femesher::TetQuality> quality;
  std::string error;
};

void buildSurface(SurfaceJob& job) {
  try {
    const femesher::TetMesh& m = *job.mesh;
    const std::vector<femesher::InterfaceTriangle> tris = femesher::extractInterfaces(m);
    std::vector<vtkIdType> index(m.points.size(), -1);
    auto pts = vtkSmartPointer<vtkPoints>::New();
    pts->SetDataTypeToDouble();
    auto polys = vtkSmartPointer<vtkCellArray>::New();
    auto labels = vtkSmartPointer<vtkIntArray>::New();
    labels->SetName("labels");
    labels->SetNumberOfTuples(vtkIdType(tris.size()));
    job.cellTets.resize(tris.size());
    for (size_t i = 0; i < tris.size(); ++i) {
      const femesher::InterfaceTriangle& t = tris[i];
      vtkIdType ids[3];
      for (int k = 0; k < 3; ++k) {
        vtkIdType& id = index[size_t(t.v[size_t(k)])];
        if (id < 0) {
          const femesher::Vec3& p = m.points[size_t(t.v[size_t(k)])];
          id = pts->InsertNextPoint(p[0], p[1], p[2]);
        }
        ids[k] = id;
      }
      polys->InsertNextCell(3, ids);
      // Colour an interface by its higher label (inner structures are usually numbered later).
      const bool useB = t.tetB >= 0;
      labels->SetValue(vtkIdType(i), useB ? t.labelB : t.labelA);
      job.cellTets[i] = {{useB ? t.tetB : t.tetA, useB ? t.tetA : t.tetB}};
    }
    job.poly = vtkSmartPointer<vtkPolyData>::New();
    job.poly->SetPoints(pts);
    job.poly->SetPolys(polys);
    job.poly->GetCellData()->AddArray(labels);
    job.quality = std::make_unique<femesher::TetQuality>(femesher::computeTetQuality(m));
  } catch (const std::exception& e) {
    job.error = e.what();
  }
}

/// What a worker builds when a label map is opened: the surfaces of its labels
/// (vtkDiscreteFlyingEdges3D on the map, every `stride`-th voxel of a large one), in LPS mm, with
/// each point coloured by its label.
struct InputJob {
  vtkSmartPointer<vtkImageData> image;  ///< the (subsampled) labels, index frame
  double affine[3][4] = {};             ///< image index -> LPS mm
  std::vector<std::pair<int32_t, std::array<unsigned char, 3>>> colors;
  vtkSmartPointer<vtkPolyData> poly;
};

void buildInputSurface(InputJob& job) {
  auto fe = vtkSmartPointer<vtkDiscreteFlyingEdges3D>::New();
  fe->SetInputData(job.image);
  for (size_t i = 0; i < job.colors.size(); ++i) fe->SetValue(int(i), job.colors[i].first);
  fe->ComputeScalarsOn();
  fe->ComputeNormalsOff();
  fe->ComputeGradientsOff();
  fe->Update();
  job.poly = vtkSmartPointer<vtkPolyData>::New();
  job.poly->ShallowCopy(fe->GetOutput());
  vtkPoints* pts = job.poly->GetPoints();
  vtkDataArray* scalars = job.poly->GetPointData()->GetScalars();
  auto rgb = vtkSmartPointer<vtkUnsignedCharArray>::New();
  rgb->SetName("colors");
  rgb->SetNumberOfComponents(3);
  const vtkIdType n = pts ? pts->GetNumberOfPoints() : 0;
  rgb->SetNumberOfTuples(n);
  for (vtkIdType i = 0; i < n; ++i) {
    double x[3], y[3];
    pts->GetPoint(i, x);
    for (int r = 0; r < 3; ++r)
      y[r] = job.affine[r][0] * x[0] + job.affine[r][1] * x[1] + job.affine[r][2] * x[2] + job.affine[r][3];
    pts->SetPoint(i, y);
    const int32_t label = scalars ? int32_t(std::lround(scalars->GetTuple1(i))) : 0;
    std::array<unsigned char, 3> c{{200, 200, 200}};
    for (const auto& [id, color] : job.colors)
      if (id == label) c = color;
    rgb->SetTypedTuple(i, c.data());
  }
  job.poly->GetPointData()->SetScalars(rgb);
}

vtkSmartPointer<vtkPolyData> legendSymbol() {
  auto s = vtkSmartPointer<vtkSphereSource>::New();
  s->SetThetaResolution(12);
  s->SetPhiResolution(8);
  s->Update();
  vtkSmartPointer<vtkPolyData> out = s->GetOutput();
  return out;
}

}  // namespace

qFEMesherPreviewView::qFEMesherPreviewView(QWidget* parent) : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->setSpacing(2);

  vtkWidget_ = new QVTKOpenGLNativeWidget(this);
  renderWindow_ = vtkSmartPointer<vtkGenericOpenGLRenderWindow>::New();
  vtkWidget_->setRenderWindow(renderWindow_);
  vtkWidget_->setMinimumSize(320, 240);
  renderer_ = vtkSmartPointer<vtkRenderer>::New();
  renderer_->SetBackground(0.32, 0.34, 0.43);
  renderer_->SetBackground2(0.82, 0.85, 0.90);
  renderer_->GradientBackgroundOn();
  renderWindow_->AddRenderer(renderer_);
  layout->addWidget(vtkWidget_, 1);

  // Controls under the view.
  auto* controls = new QHBoxLayout;
  controls->setContentsMargins(4, 0, 4, 2);
  controls->addWidget(new QLabel(tr("Colour by:"), this));
  colorCombo_ = new QComboBox(this);
  for (const char* n : kColorByNames) colorCombo_->addItem(tr(n));
  colorCombo_->setToolTip(tr("Colour the mesh by material or by a per-tet quality metric"));
  controls->addWidget(colorCombo_);
  clipCheck_ = new QCheckBox(tr("Clip"), this);
  clipCheck_->setToolTip(tr("Cut the mesh with a plane to look inside; whole tets are kept"));
  controls->addWidget(clipCheck_);
  clipAxis_ = new QComboBox(this);
  clipAxis_->addItems({tr("Left-right (sagittal)"), tr("Front-back (coronal)"),
                       tr("Head-foot (axial)")});
  clipAxis_->setCurrentIndex(1);
  controls->addWidget(clipAxis_);
  clipSlider_ = new QSlider(Qt::Horizontal, this);
  clipSlider_->setRange(0, 100);
  clipSlider_->setValue(50);
  clipSlider_->setToolTip(tr("Position of the clipping plane"));
  controls->addWidget(clipSlider_, 1);
  layout->addLayout(controls);
  connect(colorCombo_, QOverload<int>::of(&QComboBox::currentIndexChanged), this,
          &qFEMesherPreviewView::onControlsChanged);
  connect(clipCheck_, &QCheckBox::toggled, this, &qFEMesherPreviewView::onControlsChanged);
  connect(clipAxis_, QOverload<int>::of(&QComboBox::currentIndexChanged), this,
          &qFEMesherPreviewView::onControlsChanged);
  connect(clipSlider_, &QSlider::valueChanged, this, &qFEMesherPreviewView::onControlsChanged);

  // Particles.
  points_ = vtkSmartPointer<vtkPolyData>::New();
  auto pointsMapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  pointsMapper->SetInputData(points_);
  pointsMapper->SetColorModeToDirectScalars();
  pointsMapper->SetScalarModeToUsePointData();
  pointsActor_ = vtkSmartPointer<vtkActor>::New();
  pointsActor_->SetMapper(pointsMapper);
  pointsActor_->GetProperty()->SetPointSize(5);
  pointsActor_->GetProperty()->SetRenderPointsAsSpheres(true);
  pointsActor_->VisibilityOff();
  renderer_->AddActor(pointsActor_);

  // Preview surfaces.
  surface_ = vtkSmartPointer<vtkPolyData>::New();
  auto surfaceMapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  surfaceMapper->SetInputData(surface_);
  surfaceMapper->SetColorModeToDirectScalars();
  surfaceMapper->SetScalarModeToUseCellData();
  surfaceActor_ = vtkSmartPointer<vtkActor>::New();
  surfaceActor_->SetMapper(surfaceMapper);
  surfaceActor_->GetProperty()->EdgeVisibilityOn();
  surfaceActor_->GetProperty()->SetEdgeColor(0.15, 0.15, 0.15);
  surfaceActor_->VisibilityOff();
  renderer_->AddActor(surfaceActor_);

  // Final mesh: grid -> (optional) plane extraction keeping whole cells -> outer faces.
  grid_ = vtkSmartPointer<vtkUnstructuredGrid>::New();
  shown_ = grid_;
  plane_ = vtkSmartPointer<vtkPlane>::New();
  extract_ = vtkSmartPointer<vtkExtractGeometry>::New();
  extract_->SetInputData(grid_);
  extract_->SetImplicitFunction(plane_);
  extract_->ExtractInsideOn();
  extract_->ExtractBoundaryCellsOn();
  gridSurface_ = vtkSmartPointer<vtkDataSetSurfaceFilter>::New();
  gridSurface_->SetInputData(grid_);
  meshMapper_ = vtkSmartPointer<vtkPolyDataMapper>::New();
  meshMapper_->SetInputConnection(gridSurface_->GetOutputPort());
  meshMapper_->SetScalarModeToUseCellFieldData();
  meshActor_ = vtkSmartPointer<vtkActor>::New();
  meshActor_->SetMapper(meshMapper_);
  meshActor_->GetProperty()->EdgeVisibilityOn();
  meshActor_->GetProperty()->SetEdgeColor(0.12, 0.12, 0.12);
  meshActor_->GetProperty()->SetLineWidth(0.6f);
  meshActor_->VisibilityOff();
  renderer_->AddActor(meshActor_);

  // The opened label map: its label surfaces, shown until a run draws something else.
  inputSurface_ = vtkSmartPointer<vtkPolyData>::New();
  auto inputMapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  inputMapper->SetInputData(inputSurface_);
  inputMapper->SetColorModeToDirectScalars();
  inputMapper->SetScalarModeToUsePointData();
  inputActor_ = vtkSmartPointer<vtkActor>::New();
  inputActor_->SetMapper(inputMapper);
  inputActor_->VisibilityOff();
  renderer_->AddActor(inputActor_);

  // The tet asked for by showElement(): its edges in yellow, drawn over the surfaces.
  highlight_ = vtkSmartPointer<vtkPolyData>::New();
  auto highlightMapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  highlightMapper->SetInputData(highlight_);
  highlightMapper->SetResolveCoincidentTopologyToPolygonOffset();
  highlightActor_ = vtkSmartPointer<vtkActor>::New();
  highlightActor_->SetMapper(highlightMapper);
  highlightActor_->GetProperty()->SetColor(1.0, 0.9, 0.0);
  highlightActor_->GetProperty()->SetLineWidth(4.0f);
  highlightActor_->GetProperty()->LightingOff();
  highlightActor_->VisibilityOff();
  // Drawn by a second renderer on top of the scene (same camera), so the tet shows through.
  overlay_ = vtkSmartPointer<vtkRenderer>::New();
  overlay_->SetLayer(1);
  overlay_->SetActiveCamera(renderer_->GetActiveCamera());
  overlay_->InteractiveOff();
  renderWindow_->SetNumberOfLayers(2);
  renderWindow_->AddRenderer(overlay_);
  overlay_->AddActor(highlightActor_);

  outline_ = vtkSmartPointer<vtkOutlineSource>::New();
  auto outlineMapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  outlineMapper->SetInputConnection(outline_->GetOutputPort());
  outlineActor_ = vtkSmartPointer<vtkActor>::New();
  outlineActor_->SetMapper(outlineMapper);
  outlineActor_->GetProperty()->SetColor(0.9, 0.9, 0.9);
  outlineActor_->VisibilityOff();
  renderer_->AddActor(outlineActor_);

  lut_ = vtkSmartPointer<vtkLookupTable>::New();
  lut_->SetHueRange(0.667, 0.0);  // blue (good) .. red (bad), flipped per metric
  lut_->Build();
  scalarBar_ = vtkSmartPointer<vtkScalarBarActor>::New();
  scalarBar_->SetLookupTable(lut_);
  scalarBar_->SetNumberOfLabels(5);
  scalarBar_->SetWidth(0.08);
  scalarBar_->SetHeight(0.5);
  scalarBar_->SetPosition(0.9, 0.25);
  scalarBar_->VisibilityOff();
  renderer_->AddActor2D(scalarBar_);

  legend_ = vtkSmartPointer<vtkLegendBoxActor>::New();
  legend_->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  legend_->GetPositionCoordinate()->SetValue(0.76, 0.7);
  legend_->GetPosition2Coordinate()->SetValue(0.23, 0.28);
  legend_->UseBackgroundOn();
  legend_->SetBackgroundColor(0.1, 0.1, 0.12);
  legend_->SetBackgroundOpacity(0.6);
  legend_->GetEntryTextProperty()->SetFontSize(14);
  legend_->VisibilityOff();
  renderer_->AddActor2D(legend_);

  text_ = vtkSmartPointer<vtkTextActor>::New();
  text_->GetTextProperty()->SetFontSize(16);
  text_->GetTextProperty()->SetColor(1, 1, 1);
  text_->GetTextProperty()->ShadowOn();
  text_->SetDisplayPosition(10, 10);
  renderer_->AddActor2D(text_);
  setStatusText(tr("Open a label map, then press Run."));

  // Orientation axes in the lower left corner (LPS: x = left, y = posterior, z = superior).
  auto axes = vtkSmartPointer<vtkAxesActor>::New();
  axes->SetXAxisLabelText("L");
  axes->SetYAxisLabelText("P");
  axes->SetZAxisLabelText("S");
  for (vtkCaptionActor2D* c : {axes->GetXAxisCaptionActor2D(), axes->GetYAxisCaptionActor2D(),
                               axes->GetZAxisCaptionActor2D()})
    c->GetCaptionTextProperty()->ShadowOff();
  if (vtkRenderWindowInteractor* interactor = renderWindow_->GetInteractor()) {
    axesWidget_ = vtkSmartPointer<vtkOrientationMarkerWidget>::New();
    axesWidget_->SetOrientationMarker(axes);
    axesWidget_->SetInteractor(interactor);
    axesWidget_->SetViewport(0.0, 0.06, 0.16, 0.26);
    axesWidget_->SetEnabled(1);
    axesWidget_->InteractiveOff();
  }

  redrawTimer_ = new QTimer(this);
  redrawTimer_->setSingleShot(true);
  connect(redrawTimer_, &QTimer::timeout, this, &qFEMesherPreviewView::drawPendingSnapshot);
}

qFEMesherPreviewView::~qFEMesherPreviewView() {
  for (QThread* t : workers_) {
    t->wait();
    delete t;
  }
}

std::array<double, 3> qFEMesherPreviewView::materialColor(int32_t id) const {
  if (const femesher::Material* m = femesher::findMaterial(materials_, id)) return m->color;
  return femesher::defaultLabelColor(id);
}

void qFEMesherPreviewView::updateLegend() {
  // About 3.2% of the view height per entry, anchored at the top right corner.
  const int n = legend_->GetNumberOfEntries();
  const double h = std::min(0.6, 0.038 * n + 0.015);
  legend_->GetPositionCoordinate()->SetValue(0.76, 0.985 - h);
  legend_->GetPosition2Coordinate()->SetValue(0.23, h);
}

void qFEMesherPreviewView::setStatusText(const QString& text) {
  text_->SetInput(text.toUtf8().constData());
}

void qFEMesherPreviewView::setMaterials(const std::vector<femesher::Material>& materials) {
  materials_ = materials;
}

void qFEMesherPreviewView::setVolume(const femesher::LabelVolume& volume) {
  clear();
  materials_ = volume.materials;
  // Physical bounds of the voxel centres (all 8 corners through the direction matrix).
  double b[6] = {1e300, -1e300, 1e300, -1e300, 1e300, -1e300};
  for (int c = 0; c < 8; ++c) {
    const femesher::Vec3 ijk{{double((c & 1) ? volume.dims[0] - 1 : 0),
                              double((c & 2) ? volume.dims[1] - 1 : 0),
                              double((c & 4) ? volume.dims[2] - 1 : 0)}};
    const femesher::Vec3 p = volume.indexToPhysical(ijk);
    for (int a = 0; a < 3; ++a) {
      b[2 * a] = std::min(b[2 * a], p[a]);
      b[2 * a + 1] = std::max(b[2 * a + 1], p[a]);
    }
  }
  std::copy(b, b + 6, bounds_);
  outline_->SetBounds(bounds_);
  outlineActor_->VisibilityOn();
  content_ = Content::Volume;
  startInputSurface(volume);
  resetCamera(bounds_);
  setStatusText(tr("%1 x %2 x %3 voxels, %4 materials. Press Run to mesh.")
                    .arg(volume.dims[0]).arg(volume.dims[1]).arg(volume.dims[2])
                    .arg(volume.materials.size()));
  legendPairs_.clear();
  legend_->SetNumberOfEntries(int(materials_.size()));
  auto symbol = legendSymbol();
  for (size_t i = 0; i < materials_.size(); ++i) {
    double c[3] = {materials_[i].color[0], materials_[i].color[1], materials_[i].color[2]};
    const std::string s = std::to_string(materials_[i].id) + "  " + materials_[i].name;
    legend_->SetEntry(int(i), symbol, s.c_str(), c);
  }
  legend_->SetVisibility(!materials_.empty());
  updateLegend();
  renderNow();
}

void qFEMesherPreviewView::clear() {
  redrawTimer_->stop();
  pending_.reset();
  mesh_.reset();
  quality_.reset();
  highlighted_ = -1;
  highlightActor_->VisibilityOff();
  ++meshGeneration_;
  ++inputGeneration_;
  preparingInput_ = false;
  inputSurface_->Initialize();
  inputActor_->VisibilityOff();
  preparing_ = false;
  surfaceOnly_ = false;
  cellTets_.clear();
  meshSurface_ = nullptr;
  shown_ = grid_;
  points_->Initialize();
  surface_->Initialize();
  grid_->Initialize();
  pointsActor_->VisibilityOff();
  surfaceActor_->VisibilityOff();
  meshActor_->VisibilityOff();
  scalarBar_->VisibilityOff();
  displayedPoints_ = 0;
  snapshotsShown_ = 0;
  content_ = Content::Empty;
  setStatusText(tr("Open a label map, then press Run."));
  renderNow();
}

void qFEMesherPreviewView::startInputSurface(const femesher::LabelVolume& volume) {
  const int generation = ++inputGeneration_;
  auto job = std::make_shared<InputJob>();
  for (const auto& m : volume.materials) {
    if (m.id == 0 && !volume.hasNoBackground()) continue;
    const auto c = materialColor(m.id);
    job->colors.push_back({m.id, {{static_cast<unsigned char>(255 * c[0]),
                                   static_cast<unsigned char>(255 * c[1]),
                                   static_cast<unsigned char>(255 * c[2])}}});
  }
  if (job->colors.empty() || volume.voxelCount() == 0) return;
  // Every stride-th voxel of a large map (at most about kMaxInputVoxels), padded by one voxel
  // of background so the surfaces close at the edges.
  constexpr double kMaxInputVoxels = 4.0e6;
  int stride = 1;
  while (double(volume.voxelCount()) / double(stride * stride * stride) > kMaxInputVoxels) ++stride;
  inputStride_ = stride;
  int d[3];
  for (int a = 0; a < 3; ++a) d[a] = (volume.dims[a] + stride - 1) / stride + 2;
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(d[0], d[1], d[2]);
  auto values = vtkSmartPointer<vtkIntArray>::New();
  values->SetNumberOfTuples(vtkIdType(d[0]) * d[1] * d[2]);
  values->FillValue(volume.hasNoBackground() ? std::numeric_limits<int>::min() : 0);
  for (int k = 0; k + 2 < d[2]; ++k)
    for (int j = 0; j + 2 < d[1]; ++j)
      for (int i = 0; i + 2 < d[0]; ++i)
        values->SetValue(vtkIdType(i + 1) + vtkIdType(d[0]) * (vtkIdType(j + 1) + vtkIdType(d[1]) * (k + 1)),
                         volume.at(i * stride, j * stride, k * stride));
  image->GetPointData()->SetScalars(values);
  job->image = image;
  // Image index (i, j, k) is voxel ((i - 1) s, (j - 1) s, (k - 1) s): an affine map to LPS.
  const femesher::Vec3 o = volume.indexToPhysical({{-double(stride), -double(stride), -double(stride)}});
  for (int a = 0; a < 3; ++a) {
    femesher::Vec3 e{{-double(stride), -double(stride), -double(stride)}};
    e[size_t(a)] += stride;
    const femesher::Vec3 p = volume.indexToPhysical(e);
    for (int r = 0; r < 3; ++r) job->affine[r][a] = p[size_t(r)] - o[size_t(r)];
  }
  for (int r = 0; r < 3; ++r) job->affine[r][3] = o[size_t(r)];
  preparingInput_ = true;
  QThread* worker = QThread::create([job] { buildInputSurface(*job); });
  workers_ << worker;
  connect(worker, &QThread::finished, this, [this, worker, job, generation] {
    workers_.removeOne(worker);
    worker->deleteLater();
    if (generation != inputGeneration_) return;
    preparingInput_ = false;
    inputSurface_->ShallowCopy(job->poly);
    inputSurface_->Modified();
    inputActor_->SetVisibility(content_ == Content::Volume);
    renderNow();
  });
  worker->start(QThread::LowPriority);
}

size_t qFEMesherPreviewView::inputTriangleCount() const {
  return size_t(inputSurface_->GetNumberOfPolys());
}

void qFEMesherPreviewView::resetCamera(const double b[6]) {
  vtkCamera* cam = renderer_->GetActiveCamera();
  const double c[3] = {0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5])};
  // Anterior view (LPS: anterior = -y), superior up, slightly from the left for depth.
  cam->SetFocalPoint(c);
  cam->SetPosition(c[0] + 0.35, c[1] - 1.0, c[2] + 0.25);
  cam->SetViewUp(0, 0, 1);
  renderer_->ResetCamera(const_cast<double*>(b));
  cam->Zoom(1.15);
  renderer_->ResetCameraClippingRange();
}

void qFEMesherPreviewView::showSnapshot(std::shared_ptr<const femesher::PreviewSnapshot> s) {
  if (!s) return;
  pending_ = std::move(s);
  const qint64 now = QDateTime::currentMSecsSinceEpoch();
  const qint64 wait = std::max<qint64>(0, lastRedraw_ + minRedrawMs_ - now);
  if (!redrawTimer_->isActive()) redrawTimer_->start(int(wait));
}

void qFEMesherPreviewView::drawPendingSnapshot() {
  auto s = std::move(pending_);
  pending_.reset();
  if (!s) return;
  lastRedraw_ = QDateTime::currentMSecsSinceEpoch();
  // Colours per group (material pair), stable through the run.
  std::vector<std::array<unsigned char, 3>> groupColor(s->groups.size());
  for (size_t g = 0; g < s->groups.size(); ++g) {
    auto it = std::find(legendPairs_.begin(), legendPairs_.end(), s->groups[g]);
    size_t idx = size_t(it - legendPairs_.begin());
    if (it == legendPairs_.end()) legendPairs_.push_back(s->groups[g]);
    const double* c = kPairPalette[idx % kPairPaletteSize];
    groupColor[g] = {{static_cast<unsigned char>(255 * c[0]), static_cast<unsigned char>(255 * c[1]),
                      static_cast<unsigned char>(255 * c[2])}};
  }
  auto colorOf = [&](size_t i) -> std::array<unsigned char, 3> {
    if (i < s->pointGroup.size() && s->pointGroup[i] >= 0 &&
        size_t(s->pointGroup[i]) < groupColor.size())
      return groupColor[size_t(s->pointGroup[i])];
    return {{230, 230, 230}};
  };
  auto pts = vtkSmartPointer<vtkPoints>::New();
  pts->SetDataTypeToFloat();
  pts->SetNumberOfPoints(vtkIdType(s->points.size()));
  for (size_t i = 0; i < s->points.size(); ++i)
    pts->SetPoint(vtkIdType(i), s->points[i][0], s->points[i][1], s->points[i][2]);

  meshActor_->VisibilityOff();
  inputActor_->VisibilityOff();
  highlightActor_->VisibilityOff();
  scalarBar_->VisibilityOff();
  if (s->kind == "surface" && !s->triangles.empty()) {
    auto tris = vtkSmartPointer<vtkCellArray>::New();
    auto colors = vtkSmartPointer<vtkUnsignedCharArray>::New();
    colors->SetNumberOfComponents(3);
    colors->SetName("colors");
    for (const auto& t : s->triangles) {
      const vtkIdType ids[3] = {t[0], t[1], t[2]};
      tris->InsertNextCell(3, ids);
      const auto c = colorOf(size_t(t[0]));
      colors->InsertNextTypedTuple(c.data());
    }
    surface_->Initialize();
    surface_->SetPoints(pts);
    surface_->SetPolys(tris);
    surface_->GetCellData()->SetScalars(colors);
    surface_->Modified();
    surfaceActor_->VisibilityOn();
    pointsActor_->VisibilityOff();
  } else {
    auto verts = vtkSmartPointer<vtkCellArray>::New();
    auto colors = vtkSmartPointer<vtkUnsignedCharArray>::New();
    colors->SetNumberOfComponents(3);
    colors->SetName("colors");
    colors->SetNumberOfTuples(vtkIdType(s->points.size()));
    for (size_t i = 0; i < s->points.size(); ++i) {
      const vtkIdType id = vtkIdType(i);
      verts->InsertNextCell(1, &id);
      const auto c = colorOf(i);
      colors->SetTypedTuple(id, c.data());
    }
    points_->Initialize();
    points_->SetPoints(pts);
    points_->SetVerts(verts);
    points_->GetPointData()->SetScalars(colors);
    points_->Modified();
    pointsActor_->VisibilityOn();
    surfaceActor_->VisibilityOff();
  }
  displayedPoints_ = s->points.size();
  content_ = Content::Preview;
  ++snapshotsShown_;

  // Legend: interface pairs present in this snapshot.
  auto symbol = legendSymbol();
  legend_->SetNumberOfEntries(int(std::min<size_t>(s->groups.size(), 14)));
  for (size_t g = 0; g < s->groups.size() && g < 14; ++g) {
    const auto [a, b] = s->groups[g];
    auto nameOf = [&](int32_t id) -> std::string {
      if (id < 0) return "outside";
      const femesher::Material* m = femesher::findMaterial(materials_, id);
      return m ? m->name : "label " + std::to_string(id);
    };
    const std::string text = nameOf(a) + " | " + nameOf(b);
    double c[3] = {groupColor[g][0] / 255.0, groupColor[g][1] / 255.0, groupColor[g][2] / 255.0};
    legend_->SetEntry(int(g), symbol, text.c_str(), c);
  }
  legend_->SetVisibility(!s->groups.empty());
  updateLegend();
  QString what = s->kind == "surface" ? tr("%1: surface preview, %2 triangles")
                                            .arg(QString::fromStdString(s->stage))
                                            .arg(s->triangles.size())
                                      : tr("%1: %2 particles on %3 interfaces")
                                            .arg(QString::fromStdString(s->stage))
                                            .arg(s->points.size())
                                            .arg(s->groups.size());
  if (s->iteration > 0) what += tr(", iteration %1").arg(s->iteration);
  setStatusText(what);
  renderWindow_->Render();
  vtkWidget_->update();
  emit snapshotDrawn(int(s->points.size()));
}

void qFEMesherPreviewView::setMesh(std::shared_ptr<const femesher::TetMesh> mesh) {
  redrawTimer_->stop();
  pending_.reset();
  mesh_ = std::move(mesh);
  quality_.reset();
  const int generation = ++meshGeneration_;
  preparing_ = false;
  if (!mesh_) return;
  for (const auto& m : mesh_->materials)
    if (!femesher::findMaterial(materials_, m.id)) materials_.push_back(m);

  if (mesh_->tets.size() < surfaceThreshold_) {
    surfaceOnly_ = false;
    cellTets_.clear();
    meshSurface_ = nullptr;
    femesher::meshToVtkGrid(*mesh_, grid_);  // LPS, cell array "labels"
    shown_ = grid_;
    finishMesh();
    return;
  }
  // Large: the surfaces and the quality are built off the GUI thread.
  preparing_ = true;
  auto job = std::make_shared<SurfaceJob>();
  job->mesh = mesh_;
  QThread* worker = QThread::create([job] { buildSurface(*job); });
  workers_ << worker;
  connect(worker, &QThread::finished, this, [this, worker, job, generation] {
    workers_.removeOne(worker);
    worker->deleteLater();
    if (generation != meshGeneration_) return;  // another mesh came meanwhile
    preparing_ = false;
    if (!job->poly) {
      setStatusText(tr("Cannot draw the mesh: %1").arg(QString::fromStdString(job->error)));
      renderNow();
      return;
    }
    surfaceOnly_ = true;
    meshSurface_ = job->poly;
    cellTets_ = std::move(job->cellTets);
    quality_ = std::move(job->quality);
    grid_->Initialize();
    shown_ = meshSurface_;
    finishMesh();
  });
  worker->start(QThread::LowPriority);
  setStatusText(tr("Preparing the surfaces of the mesh (%1 tets)…").arg(mesh_->tets.size()));
  renderNow();
}

void qFEMesherPreviewView::finishMesh() {
  if (!quality_) quality_ = std::make_shared<const femesher::TetQuality>(femesher::computeTetQuality(*mesh_));
  highlighted_ = -1;
  highlightActor_->VisibilityOff();
  updateMeshColors();
  updateClipPlane();
  {  // frame the mesh (same viewing direction)
    double mb[6];
    shown_->GetBounds(mb);
    renderer_->ResetCamera(mb);
    renderer_->GetActiveCamera()->Zoom(1.1);
  }
  showMeshActors();
  emit meshShown(mesh_, quality_);
}

bool qFEMesherPreviewView::showElement(size_t tet) {
  if (!mesh_ || preparing_ || content_ != Content::Mesh || tet >= mesh_->tets.size()) return false;
  const auto& t = mesh_->tets[tet];
  auto pts = vtkSmartPointer<vtkPoints>::New();
  double c[3] = {0, 0, 0}, minY = 1e300, longest = 0;
  for (int k = 0; k < 4; ++k) {
    const femesher::Vec3& p = mesh_->points[size_t(t[size_t(k)])];
    pts->InsertNextPoint(p[0], p[1], p[2]);
    for (int a = 0; a < 3; ++a) c[a] += 0.25 * p[size_t(a)];
    minY = std::min(minY, p[1]);
    for (int l = 0; l < k; ++l) {
      const femesher::Vec3& q = mesh_->points[size_t(t[size_t(l)])];
      longest = std::max(longest, std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                                            (p[2] - q[2]) * (p[2] - q[2])));
    }
  }
  auto lines = vtkSmartPointer<vtkCellArray>::New();
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      const vtkIdType e[2] = {a, b};
      lines->InsertNextCell(2, e);
    }
  highlight_->Initialize();
  highlight_->SetPoints(pts);
  highlight_->SetLines(lines);
  highlight_->Modified();
  highlightActor_->VisibilityOn();
  highlighted_ = (long long)tet;
  // Cut just in front of the tet (it lies wholly on the kept, far side) and look at the cut face.
  double b[6];
  shown_->GetBounds(b);
  const double span = b[3] > b[2] ? b[3] - b[2] : 1.0;
  setClipping(true, 1, std::floor(100.0 * (minY - b[2]) / span) / 100.0);
  vtkCamera* cam = renderer_->GetActiveCamera();
  const double dist = std::max(12.0 * longest, 1e-3);
  cam->SetFocalPoint(c);
  cam->SetPosition(c[0] + 0.25 * dist, c[1] - dist, c[2] + 0.25 * dist);
  cam->SetViewUp(0, 0, 1);
  setStatusText(tr("Tet %1 (material %2)").arg(tet).arg(mesh_->tetLabels[tet]));
  renderNow();
  return true;
}

double qFEMesherPreviewView::cameraFocalPoint(int axis) const {
  return renderer_->GetActiveCamera()->GetFocalPoint()[std::clamp(axis, 0, 2)];
}

bool qFEMesherPreviewView::restoreMesh() {
  redrawTimer_->stop();
  pending_.reset();
  if (!mesh_) return false;
  if (!preparing_) showMeshActors();  // else it shows once its surfaces are built
  return true;
}

void qFEMesherPreviewView::showMeshActors() {
  inputActor_->VisibilityOff();
  pointsActor_->VisibilityOff();
  surfaceActor_->VisibilityOff();
  meshActor_->VisibilityOn();
  content_ = Content::Mesh;
  // Legend: the materials of the mesh.
  auto symbol = legendSymbol();
  legend_->SetNumberOfEntries(int(mesh_->materials.size()));
  for (size_t i = 0; i < mesh_->materials.size(); ++i) {
    const auto c3 = materialColor(mesh_->materials[i].id);
    double c[3] = {c3[0], c3[1], c3[2]};
    const std::string s = std::to_string(mesh_->materials[i].id) + "  " + mesh_->materials[i].name;
    legend_->SetEntry(int(i), symbol, s.c_str(), c);
  }
  legend_->SetVisibility(colorBy() == ColorBy::Material && !mesh_->materials.empty());
  updateLegend();
  QString status = tr("Mesh: %1 vertices, %2 tets, %3 materials")
                       .arg(mesh_->points.size()).arg(mesh_->tets.size())
                       .arg(mesh_->materials.size());
  if (surfaceOnly_)
    status += tr(" (drawn as %1 boundary and interface triangles)").arg(shown_->GetNumberOfCells());
  setStatusText(status);
  renderNow();
}

size_t qFEMesherPreviewView::displayedCellCount() const {
  if (content_ != Content::Mesh) return 0;
  vtkDataSet* in = isClipping() ? vtkDataSet::SafeDownCast(extract_->GetOutput()) : shown_;
  return in ? size_t(in->GetNumberOfCells()) : 0;
}

void qFEMesherPreviewView::updateMeshColors() {
  if (!mesh_) return;
  const ColorBy mode = colorBy();
  if (preparing_) return;  // coloured once the surfaces are there
  const vtkIdType n = shown_->GetNumberOfCells();
  if (mode == ColorBy::Material) {
    auto colors = vtkSmartPointer<vtkUnsignedCharArray>::New();
    colors->SetName("colors");
    colors->SetNumberOfComponents(3);
    colors->SetNumberOfTuples(n);
    std::map<int32_t, std::array<unsigned char, 3>> cache;
    for (vtkIdType t = 0; t < n; ++t) {
      const int32_t l = mesh_->tetLabels[cellTets_.empty() ? size_t(t) : size_t(cellTets_[size_t(t)][0])];
      auto it = cache.find(l);
      if (it == cache.end()) {
        const auto c = materialColor(l);
        it = cache.emplace(l, std::array<unsigned char, 3>{
                                  {static_cast<unsigned char>(255 * c[0]),
                                   static_cast<unsigned char>(255 * c[1]),
                                   static_cast<unsigned char>(255 * c[2])}}).first;
      }
      colors->SetTypedTuple(t, it->second.data());
    }
    shown_->GetCellData()->RemoveArray("colors");
    shown_->GetCellData()->AddArray(colors);
    meshMapper_->SetColorModeToDirectScalars();
    meshMapper_->SelectColorArray("colors");
    meshMapper_->SetScalarModeToUseCellFieldData();
    meshMapper_->ScalarVisibilityOn();
    scalarBar_->VisibilityOff();
    legend_->SetVisibility(!mesh_->materials.empty());
  } else {
    if (!quality_) quality_ = std::make_shared<const femesher::TetQuality>(femesher::computeTetQuality(*mesh_));
    const std::vector<double>* values = nullptr;
    double lo = 0, hi = 1;
    bool highIsBad = true;
    const char* title = "";
    switch (mode) {
      case ColorBy::AspectRatio: values = &quality_->aspectRatio; lo = 1; hi = 4; title = "Aspect ratio"; break;
      case ColorBy::RadiusRatio: values = &quality_->radiusRatio; lo = 1; hi = 4; title = "Radius ratio"; break;
      case ColorBy::MinDihedral: values = &quality_->minDihedral; lo = 0; hi = 70.53; highIsBad = false; title = "Min dihedral"; break;
      case ColorBy::ScaledJacobian: values = &quality_->scaledJacobian; lo = 0; hi = 1; highIsBad = false; title = "Scaled Jacobian"; break;
      default: break;
    }
    auto arr = vtkSmartPointer<vtkDoubleArray>::New();
    arr->SetName("metric");
    arr->SetNumberOfTuples(n);
    for (vtkIdType t = 0; t < n; ++t) {
      double v = values ? cellMetric(*values, size_t(t), highIsBad) : 0.0;
      if (!std::isfinite(v)) v = highIsBad ? hi : lo;
      arr->SetValue(t, v);
    }
    shown_->GetCellData()->RemoveArray("metric");
    shown_->GetCellData()->AddArray(arr);
    lut_->SetHueRange(highIsBad ? 0.667 : 0.0, highIsBad ? 0.0 : 0.667);
    lut_->SetTableRange(lo, hi);
    lut_->Build();
    meshMapper_->SetLookupTable(lut_);
    meshMapper_->SetColorModeToMapScalars();
    meshMapper_->SetScalarRange(lo, hi);
    meshMapper_->SelectColorArray("metric");
    meshMapper_->SetScalarModeToUseCellFieldData();
    meshMapper_->UseLookupTableScalarRangeOff();
    meshMapper_->ScalarVisibilityOn();
    scalarBar_->SetTitle(title);
    scalarBar_->VisibilityOn();
    legend_->VisibilityOff();
  }
  shown_->Modified();
}

double qFEMesherPreviewView::cellMetric(const std::vector<double>& values, size_t cell,
                                        bool highIsBad) const {
  auto at = [&](int32_t tet) {
    return tet >= 0 && size_t(tet) < values.size() ? values[size_t(tet)]
                                                   : std::numeric_limits<double>::quiet_NaN();
  };
  if (cellTets_.empty()) return at(int32_t(cell));
  const double a = at(cellTets_[cell][0]), b = at(cellTets_[cell][1]);
  if (!std::isfinite(b)) return a;
  if (!std::isfinite(a)) return b;
  return highIsBad ? std::max(a, b) : std::min(a, b);  // the worse side
}

void qFEMesherPreviewView::updateClipPlane() {
  const bool on = clipCheck_->isChecked();
  const int axis = clipAxis_->currentIndex();
  double b[6];
  if (shown_->GetNumberOfPoints() > 0) shown_->GetBounds(b);
  else std::copy(bounds_, bounds_ + 6, b);
  const double f = clipSlider_->value() / 100.0;
  double origin[3] = {0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5])};
  origin[axis] = b[2 * axis] + f * (b[2 * axis + 1] - b[2 * axis]);
  double normal[3] = {0, 0, 0};
  normal[axis] = -1;  // keep the far half (seen from the camera on the negative side)
  plane_->SetOrigin(origin);
  plane_->SetNormal(normal);
  plane_->Modified();
  gridSurface_->SetInputConnection(on ? extract_->GetOutputPort() : nullptr);
  if (!on) gridSurface_->SetInputData(shown_);
  else extract_->SetInputData(shown_);
}

void qFEMesherPreviewView::onControlsChanged() {
  if (sender() == colorCombo_) updateMeshColors();
  if (sender() == clipAxis_ && content_ == Content::Mesh) {
    // Look at the cut face: camera on the negative side of the chosen axis.
    double b[6];
    shown_->GetBounds(b);
    vtkCamera* cam = renderer_->GetActiveCamera();
    const double c[3] = {0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5])};
    double pos[3] = {c[0] + 0.3, c[1] + 0.3, c[2] + 0.3};
    pos[clipAxis_->currentIndex()] -= 1.3;
    cam->SetFocalPoint(c);
    cam->SetPosition(pos);
    cam->SetViewUp(clipAxis_->currentIndex() == 2 ? 0 : 0, clipAxis_->currentIndex() == 2 ? 1 : 0,
                   clipAxis_->currentIndex() == 2 ? 0 : 1);
    renderer_->ResetCamera(b);
  }
  updateClipPlane();
  renderNow();
}

void qFEMesherPreviewView::setColorBy(ColorBy mode) { colorCombo_->setCurrentIndex(int(mode)); }

qFEMesherPreviewView::ColorBy qFEMesherPreviewView::colorBy() const {
  return ColorBy(std::max(0, colorCombo_->currentIndex()));
}

void qFEMesherPreviewView::setClipping(bool on, int axis, double fraction) {
  clipAxis_->setCurrentIndex(std::clamp(axis, 0, 2));
  clipSlider_->setValue(int(std::lround(std::clamp(fraction, 0.0, 1.0) * 100)));
  clipCheck_->setChecked(on);
  updateClipPlane();
  renderNow();
}

bool qFEMesherPreviewView::isClipping() const { return clipCheck_->isChecked(); }

void qFEMesherPreviewView::renderNow() {
  if (pending_) {
    drawPendingSnapshot();
    return;
  }
  renderer_->ResetCameraClippingRange();
  renderWindow_->Render();
  vtkWidget_->update();
}

QImage qFEMesherPreviewView::grabRenderImage() {
  if (pending_) drawPendingSnapshot();
  renderNow();
  return vtkWidget_->grabFramebuffer();
}
