// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file qFEMesherPreviewView.h
/// The 3-D view: during a run the live preview snapshots (particles of every interface coloured by
/// material pair, or preview surfaces); afterwards the tet mesh coloured by material or by a
/// quality metric, with a clipping plane that keeps whole cells so one can look inside.
/// Redraws are throttled (at most one every `minRedrawInterval` ms); the newest snapshot wins.
///
/// Large meshes (at least `surfaceOnlyThreshold()` tets, 150 000 by default) are drawn as their
/// surfaces only: the outer boundary and the interfaces between materials (`extractInterfaces`),
/// built with the per-tet quality in a worker thread so the window stays responsive; each
/// triangle is coloured by its tet (by the worse of its two tets for a quality metric), and the
/// clipping plane then shows the interfaces inside. Smaller meshes are drawn as whole tets.
/// Needs an OpenGL context (a real or virtual X server, e.g. `xvfb-run`).

#include <femesher/RunContext.h>
#include <femesher/Types.h>
#include <femesher/stages/Quality.h>

#include <QImage>
#include <QList>
#include <QWidget>

#include <vtkSmartPointer.h>

#include <memory>

class QCheckBox;
class QComboBox;
class QLabel;
class QSlider;
class QThread;
class QTimer;
class QVTKOpenGLNativeWidget;
class vtkActor;
class vtkDataSet;
class vtkDataSetSurfaceFilter;
class vtkExtractGeometry;
class vtkGenericOpenGLRenderWindow;
class vtkLegendBoxActor;
class vtkLookupTable;
class vtkOrientationMarkerWidget;
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

  /// A new input: remembers its materials (colours, names), draws its bounding box and its label
  /// surfaces (vtkDiscreteFlyingEdges3D, built in a worker thread on every `inputStride()`-th
  /// voxel so that at most about 4 M voxels are used), resets the camera and drops any previous
  /// preview or mesh. Orientation axes (L, P, S) sit in the lower left corner.
  void setVolume(const femesher::LabelVolume& volume);
  void setMaterials(const std::vector<femesher::Material>& materials);
  /// Show the final mesh (replaces the preview). A large mesh appears once its surfaces are
  /// built in the background (`isPreparingMesh()` meanwhile); the call itself returns at once.
  void setMesh(std::shared_ptr<const femesher::TetMesh> mesh);
  /// Meshes with at least this many tets are drawn as surfaces only (see above).
  void setSurfaceOnlyThreshold(size_t tets) { surfaceThreshold_ = tets; }
  size_t surfaceOnlyThreshold() const { return surfaceThreshold_; }
  /// True while the opened label map's surfaces are being built.
  bool isPreparingInput() const { return preparingInput_; }
  /// Triangles of the label map's surfaces (0 before they are built).
  size_t inputTriangleCount() const;
  /// 1, or the step between the voxels the label surfaces were built from (large maps).
  int inputStride() const { return inputStride_; }
  /// True while a large mesh's surfaces are being built.
  bool isPreparingMesh() const { return preparing_; }
  /// True when the mesh shown is drawn as surfaces only (then displayedCellCount() counts
  /// triangles).
  bool isSurfaceOnly() const { return surfaceOnly_; }
  /// Show the last mesh given to setMesh() again in place of the live preview (after a canceled
  /// or failed run). False when there is none.
  bool restoreMesh();
  void clear();

  /// Point the camera at tet `tet` of the mesh shown, cut the mesh just in front of it (the
  /// front-back plane) and outline it in yellow. False if there is no such tet (or the mesh is
  /// still being prepared).
  bool showElement(size_t tet);
  /// The outlined tet, -1 when none.
  long long highlightedElement() const { return highlighted_; }
  double cameraFocalPoint(int axis) const;

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
  /// A mesh is on screen, with its per-tet quality (computed off the GUI thread for large ones).
  void meshShown(std::shared_ptr<const femesher::TetMesh> mesh,
                 std::shared_ptr<const femesher::TetQuality> quality);

 private slots:
  void drawPendingSnapshot();
  void onControlsChanged();

 private:
  void resetCamera(const double bounds[6]);
  void showMeshActors();
  void finishMesh();
  void startInputSurface(const femesher::LabelVolume& volume);
  double cellMetric(const std::vector<double>& values, size_t cell, bool highIsBad) const;
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
  vtkSmartPointer<vtkPolyData> meshSurface_;  ///< surfaces of a large mesh
  vtkDataSet* shown_ = nullptr;               ///< grid_ or meshSurface_
  /// Surface mode: the tet(s) on each side of each triangle (-1 on the boundary).
  std::vector<std::array<int32_t, 2>> cellTets_;
  vtkSmartPointer<vtkPlane> plane_;
  vtkSmartPointer<vtkExtractGeometry> extract_;
  vtkSmartPointer<vtkDataSetSurfaceFilter> gridSurface_;
  vtkSmartPointer<vtkPolyDataMapper> meshMapper_;
  vtkSmartPointer<vtkActor> meshActor_;
  vtkSmartPointer<vtkPolyData> inputSurface_;
  vtkSmartPointer<vtkActor> inputActor_;
  vtkSmartPointer<vtkOrientationMarkerWidget> axesWidget_;
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
  std::shared_ptr<const femesher::TetQuality> quality_;  ///< per-tet values of mesh_
  vtkSmartPointer<vtkPolyData> highlight_;
  vtkSmartPointer<vtkActor> highlightActor_;
  vtkSmartPointer<vtkRenderer> overlay_;
  long long highlighted_ = -1;
  std::shared_ptr<const femesher::PreviewSnapshot> pending_;
  std::vector<std::pair<int32_t, int32_t>> legendPairs_;
  Content content_ = Content::Empty;
  double bounds_[6] = {0, 1, 0, 1, 0, 1};
  size_t displayedPoints_ = 0;
  int snapshotsShown_ = 0;
  int minRedrawMs_ = 100;
  size_t surfaceThreshold_ = 150000;
  bool surfaceOnly_ = false;
  bool preparing_ = false;
  int meshGeneration_ = 0;
  int inputGeneration_ = 0;
  bool preparingInput_ = false;
  int inputStride_ = 1;      ///< a surface built for an older setMesh() is dropped
  QList<QThread*> workers_;     ///< surface builders still running (joined by the destructor)
  qint64 lastRedraw_ = 0;
};
