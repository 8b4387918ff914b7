// SPDX-License-Identifier: GPL-3.0-or-later
// The 3-D view under a virtual X server: live snapshots are drawn (and throttled, the newest
// wins), the mesh is shown coloured by material, clipping keeps whole cells on one side, metric
// colouring works, and the rendered image really shows the material colours.
#include <qFEMesherPreviewView.h>

#include <femesher/Types.h>

#include <QSurfaceFormat>
#include <QVTKOpenGLNativeWidget.h>
#include <QtTest>

using namespace femesher;

namespace {

/// Two materials side by side: an n x n x n block of cubes, 5 tets per cube (alternating
/// orientation so faces match), label 1 for x < n/2, label 2 beyond.
TetMesh makeBlockMesh(int n, double h) {
  TetMesh m;
  auto id = [n](int i, int j, int k) { return int32_t(i + (n + 1) * (j + (n + 1) * k)); };
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) m.points.push_back({{i * h, j * h, k * h}});
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        int32_t v[8];
        for (int c = 0; c < 8; ++c) v[c] = id(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
        const bool flip = (i + j + k) % 2 == 1;
        const int tets[2][5][4] = {{{0, 1, 2, 4}, {1, 3, 2, 7}, {1, 2, 4, 7}, {1, 4, 5, 7}, {2, 4, 7, 6}},
                                   {{0, 1, 3, 5}, {0, 3, 2, 6}, {0, 5, 3, 6}, {0, 5, 6, 4}, {3, 5, 7, 6}}};
        for (const auto& t : tets[flip]) {
          std::array<int32_t, 4> tet{{v[t[0]], v[t[1]], v[t[2]], v[t[3]]}};
          m.tets.push_back(tet);
          if (m.tetVolume(m.tets.size() - 1) < 0) std::swap(m.tets.back()[2], m.tets.back()[3]);
          m.tetLabels.push_back(i < n / 2 ? 1 : 2);
        }
      }
  m.materials = {{1, "bone", {{0.9, 0.1, 0.1}}}, {2, "implant", {{0.1, 0.2, 0.9}}}};
  return m;
}

/// Pixels whose chromaticity matches `c` (shading changes brightness, not the hue much).
int pixelsLike(const QImage& img, const std::array<double, 3>& c) {
  const double cs = c[0] + c[1] + c[2];
  int n = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const QColor p = img.pixelColor(x, y);
      const double s = p.redF() + p.greenF() + p.blueF();
      if (s < 0.15) continue;
      if (std::abs(p.redF() / s - c[0] / cs) < 0.06 && std::abs(p.greenF() / s - c[1] / cs) < 0.06 &&
          std::abs(p.blueF() / s - c[2] / cs) < 0.06)
        ++n;
    }
  return n;
}

std::shared_ptr<PreviewSnapshot> makeSnapshot(int count, int iteration) {
  auto s = std::make_shared<PreviewSnapshot>();
  s->stage = "ParticleSystem";
  s->kind = "points";
  s->iteration = iteration;
  s->groups = {{1, 2}, {1, -1}};
  for (int i = 0; i < count; ++i) {
    const double t = 6.283 * i / count;
    s->points.push_back({{float(10 + 8 * std::cos(t)), float(10 + 8 * std::sin(t)), float(i % 20)}});
    s->pointGroup.push_back(i % 2);
  }
  return s;
}

}  // namespace

class PreviewViewTest : public QObject {
  Q_OBJECT
 private slots:
  void snapshotsAreThrottledAndTheNewestWins() {
    qFEMesherPreviewView view;
    view.resize(640, 480);
    view.show();
    QVERIFY(QTest::qWaitForWindowExposed(&view));
    LabelVolume v;
    v.dims = {{20, 20, 20}};
    v.labels.assign(v.voxelCount(), 0);
    v.materials = {{1, "bone", {{0.9, 0.1, 0.1}}}, {2, "implant", {{0.1, 0.2, 0.9}}}};
    view.setVolume(v);
    QCOMPARE(view.content(), qFEMesherPreviewView::Content::Volume);
    view.setMinRedrawInterval(200);
    QSignalSpy drawn(&view, &qFEMesherPreviewView::snapshotDrawn);
    for (int i = 1; i <= 50; ++i) view.showSnapshot(makeSnapshot(100 + i, i));
    QTRY_VERIFY_WITH_TIMEOUT(view.displayedPointCount() == 150, 10000);
    QTest::qWait(300);
    QVERIFY2(drawn.count() < 10, qPrintable(QString("%1 redraws for 50 snapshots").arg(drawn.count())));
    QCOMPARE(view.content(), qFEMesherPreviewView::Content::Preview);
    const QImage img = view.grabRenderImage();
    QVERIFY(!img.isNull());
    QVERIFY(img.width() > 100);
  }

  void meshColouredByMaterialAndClipped() {
    qFEMesherPreviewView view;
    view.resize(640, 480);
    view.show();
    QVERIFY(QTest::qWaitForWindowExposed(&view));
    auto mesh = std::make_shared<TetMesh>(makeBlockMesh(6, 2.0));
    view.setMesh(mesh);
    QCOMPARE(view.content(), qFEMesherPreviewView::Content::Mesh);
    QImage img = view.grabRenderImage();
    const int red = pixelsLike(img, mesh->materials[0].color);
    const int blue = pixelsLike(img, mesh->materials[1].color);
    qInfo("material pixels: %d red-ish, %d blue-ish of %d", red, blue, img.width() * img.height());
    QVERIFY(red > 500);
    QVERIFY(blue > 500);
    QCOMPARE(view.displayedCellCount(), mesh->tets.size());
    // Clipping across x (the material split): whole cells of one side are kept.
    view.setClipping(true, 0, 0.5);
    QVERIFY(view.isClipping());
    const size_t kept = view.displayedCellCount();
    QVERIFY(kept > 0);
    QVERIFY(kept < mesh->tets.size());
    // vtkPlane normal -x keeps x >= cut; cells crossing the plane are kept whole, so at least half.
    QVERIFY(kept >= mesh->tets.size() / 2);
    img = view.grabRenderImage();
    QVERIFY(pixelsLike(img, mesh->materials[1].color) > 500);
    view.setClipping(false);
    QCOMPARE(view.displayedCellCount(), mesh->tets.size());
    // Colour by a metric: the material colours are gone (blue-red map + scalar bar).
    view.setColorBy(qFEMesherPreviewView::ColorBy::MinDihedral);
    QCOMPARE(view.colorBy(), qFEMesherPreviewView::ColorBy::MinDihedral);
    const QImage metric = view.grabRenderImage();
    QVERIFY(metric != img);
  }
};

int main(int argc, char* argv[]) {
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QApplication app(argc, argv);
  PreviewViewTest test;
  return QTest::qExec(&test, argc, argv);
}
#include "test_PreviewView.moc"
