// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file qFEMesherPreviewView.h
/// The 3-D view: during a run the live preview snapshots (particles of every interface coloured by
/// material pair, or preview surfaces); afterwards the tet mesh coloured by material or by a
/// quality metric, with a clipping plane that keeps whole cells so one can look inside.
/// Redraws are throttled (at most one every `minRedrawInterval` ms); the newest snapshot wins.
/// Needs an OpenGL context (a real or virtual X server, e.g. `xvfb-run`).

#include <femesher/RunContext.h>
#include <femesher/Types.h>
#include <femesher/stages/Quality.h>

#include <QImage>
#include <QWidget>

#include <vtkSmartPointer.h>

#include <memory>

class QCheckBox;
class QComboBox;
class QLabel;
class QSlider;
class QTimer;
class QVTKOpenGLNativeWidget;
class vtkActor;
class vtkDataSetSurfaceFilter;
class vtkExtractGeometry;
class vtkGenericOpenGLRenderWindow;
class vtkLegendBoxActor;
class vtkLookupTable;
class vtkOutlineSource;
class vtkPlane;
class vtkPolyData;
class vtkPolyDataMapper;
class vtkRenderer;
class vtkScalarBarActor;
class vtkTextActor;
class vtkUnstructuredGrid;

class qFEMesherPreviewView : public QWidget {
  Q_OBJECT
 public:
  enum class ColorBy { Material = 0, AspectRatio, RadiusRatio, MinDihedral, ScaledJacobian };
  enum class Content { Empty, Volume, Preview, Mesh };

  explicit qFEMesherPreviewView(QWidget* parent = nullptr);
  ~qFEMesherPreviewView() override;

  /// A new input: remembers its materials (colours, names), draws its bounding box, resets the
  /// camera and drops any previous preview or mesh.
  void setVolume(const femesher::LabelVolume& volume);
  void setMaterials(const std::vector<femesher::Material>& materials);
  /// Show the final mesh (replaces the preview).
  void setMesh(std::shared_ptr<const femesher::TetMesh> mesh);
  void clear();

  void setColorBy(ColorBy mode);
  ColorBy colorBy() const;
  /// Clipping plane perpendicular to `axis` (0 = L, 1 = P, 2 = S) at `fraction` of the bounds;
  /// cells on the far side are kept whole.
  void setClipping(bool on, int axis = 1, double fraction = 0.5);
  bool isClipping() const;

  Content content() const { return content_; }
  size_t displayedPointCount() const { return displayedPoints_; }
  size_t displayedCellCount() const;
  int snapshotsShown() const { return snapshotsShown_; }
  /// The rendered image of the VTK window (renders first).
  QImage grabRenderImage();
  QVTKOpenGLNativeWidget* vtkWidget() const { return vtkWidget_; }
  void setMinRedrawInterval(int msecs) { minRedrawMs_ = msecs; }
  /// Render now (also flushes a pending throttled snapshot).
  void renderNow();

 public slots:
  void showSnapshot(std::shared_ptr<const femesher::PreviewSnapshot> snapshot);

 signals:
  void snapshotDrawn(int pointCount);

 private slots:
  void drawPendingSnapshot();
  void onControlsChanged();

 private:
  void resetCamera(const double bounds[6]);
  void updateMeshColors();
  void updateClipPlane();
  void updateLegend();
  void setStatusText(const QString& text);
  std::array<double, 3> materialColor(int32_t id) const;

  QVTKOpenGLNativeWidget* vtkWidget_ = nullptr;
  vtkSmartPointer<vtkGenericOpenGLRenderWindow> renderWindow_;
  vtkSmartPointer<vtkRenderer> renderer_;
  vtkSmartPointer<vtkPolyData> points_;
  vtkSmartPointer<vtkActor> pointsActor_;
  vtkSmartPointer<vtkPolyData> surface_;
  vtkSmartPointer<vtkActor> surfaceActor_;
  vtkSmartPointer<vtkUnstructuredGrid> grid_;
  vtkSmartPointer<vtkPlane> plane_;
  vtkSmartPointer<vtkExtractGeometry> extract_;
  vtkSmartPointer<vtkDataSetSurfaceFilter> gridSurface_;
  vtkSmartPointer<vtkPolyDataMapper> meshMapper_;
  vtkSmartPointer<vtkActor> meshActor_;
  vtkSmartPointer<vtkOutlineSource> outline_;
  vtkSmartPointer<vtkActor> outlineActor_;
  vtkSmartPointer<vtkLookupTable> lut_;
  vtkSmartPointer<vtkScalarBarActor> scalarBar_;
  vtkSmartPointer<vtkLegendBoxActor> legend_;
  vtkSmartPointer<vtkTextActor> text_;

  QComboBox* colorCombo_ = nullptr;
  QCheckBox* clipCheck_ = nullptr;
  QComboBox* clipAxis_ = nullptr;
  QSlider* clipSlider_ = nullptr;
  QTimer* redrawTimer_ = nullptr;

  std::vector<femesher::Material> materials_;
  std::shared_ptr<const femesher::TetMesh> mesh_;
  std::unique_ptr<femesher::TetQuality> quality_;  ///< per-tet values, computed on demand
  std::shared_ptr<const femesher::PreviewSnapshot> pending_;
  std::vector<std::pair<int32_t, int32_t>> legendPairs_;
  Content content_ = Content::Empty;
  double bounds_[6] = {0, 1, 0, 1, 0, 1};
  size_t displayedPoints_ = 0;
  int snapshotsShown_ = 0;
  int minRedrawMs_ = 100;
  qint64 lastRedraw_ = 0;
};
