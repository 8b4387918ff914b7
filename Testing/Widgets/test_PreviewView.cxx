// SPDX-License-Identifier: GPL-3.0-or-later
// The 3-D view under a virtual X server: live snapshots are drawn (and throttled, the newest
// wins), the mesh is shown coloured by material, clipping keeps whole cells on one side, metric
// colouring works, and the rendered image really shows the material colours; a mesh of over
// 500 k tets is drawn as surfaces built off the GUI thread, which keeps ticking; an opened label
// map is drawn as its label surfaces.
#include <qFEMesherPreviewView.h>

#include <femesher/Types.h>

#include <QSurfaceFormat>
#include <QVTKOpenGLNativeWidget.h>
#include <QElapsedTimer>
#include <QTimer>
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
    // Showing one tet: camera on its centroid, cut in front of it, its edges in yellow.
    view.setColorBy(qFEMesherPreviewView::ColorBy::Material);
    QCOMPARE(view.highlightedElement(), -1LL);
    QVERIFY(!view.showElement(mesh->tets.size()));
    const size_t tet = mesh->tets.size() / 2 + 7;
    QVERIFY(view.showElement(tet));
    QCOMPARE(view.highlightedElement(), (long long)tet);
    for (int a = 0; a < 3; ++a) {
      double c = 0;
      for (int k = 0; k < 4; ++k) c += 0.25 * mesh->points[size_t(mesh->tets[tet][size_t(k)])][size_t(a)];
      QVERIFY(std::abs(view.cameraFocalPoint(a) - c) < 1e-9);
    }
    QVERIFY(view.isClipping());
    const int yellow = pixelsLike(view.grabRenderImage(), {{1.0, 0.9, 0.0}});
    qInfo("highlighted tet: %d yellow pixels", yellow);
    QVERIFY(yellow > 30);
  }

  void meshShownCarriesTheQuality() {
    qFEMesherPreviewView view;
    view.resize(320, 240);
    view.show();
    QVERIFY(QTest::qWaitForWindowExposed(&view));
    int shown = 0;
    size_t values = 0;
    connect(&view, &qFEMesherPreviewView::meshShown,
            [&](std::shared_ptr<const TetMesh>, std::shared_ptr<const TetQuality> q) {
              ++shown;
              values = q ? q->minDihedral.size() : 0;
            });
    auto mesh = std::make_shared<TetMesh>(makeBlockMesh(4, 1.0));
    view.setMesh(mesh);
    QCOMPARE(shown, 1);
    QCOMPARE(values, mesh->tets.size());
    view.setSurfaceOnlyThreshold(10);  // the worker path
    view.setMesh(mesh);
    QTRY_COMPARE_WITH_TIMEOUT(shown, 2, 30000);
    QCOMPARE(values, mesh->tets.size());
  }

  void openedLabelMapIsShownAsSurfaces() {
    // A ball of label 1 beside a block of label 2: both surfaces, in their colours.
    qFEMesherPreviewView view;
    view.resize(640, 480);
    view.show();
    QVERIFY(QTest::qWaitForWindowExposed(&view));
    LabelVolume v;
    v.dims = {{48, 40, 40}};
    v.spacing = {{0.5, 0.5, 0.5}};
    v.labels.assign(v.voxelCount(), 0);
    for (int k = 0; k < 40; ++k)
      for (int j = 0; j < 40; ++j)
        for (int i = 0; i < 48; ++i) {
          const double r2 = (i - 14) * (i - 14) + (j - 20) * (j - 20) + (k - 20) * (k - 20);
          if (r2 < 100) v.labels[v.index(i, j, k)] = 1;
          else if (i >= 28 && i < 44 && j >= 8 && j < 32 && k >= 8 && k < 32) v.labels[v.index(i, j, k)] = 2;
        }
    v.materials = {{1, "bone", {{0.9, 0.1, 0.1}}}, {2, "implant", {{0.1, 0.2, 0.9}}}};
    view.setVolume(v);
    QCOMPARE(view.content(), qFEMesherPreviewView::Content::Volume);
    QTRY_VERIFY_WITH_TIMEOUT(!view.isPreparingInput(), 30000);
    QCOMPARE(view.inputStride(), 1);
    QVERIFY(view.inputTriangleCount() > 500);
    const QImage img = view.grabRenderImage();
    const int red = pixelsLike(img, v.materials[0].color);
    const int blue = pixelsLike(img, v.materials[1].color);
    qInfo("label surfaces: %zu triangles, %d red-ish and %d blue-ish pixels", view.inputTriangleCount(),
          red, blue);
    QVERIFY(red > 500);
    QVERIFY(blue > 500);
    // A large map is sampled on every second voxel (or coarser).
    LabelVolume big;
    big.dims = {{200, 200, 120}};
    big.labels.assign(big.voxelCount(), 0);
    for (int k = 20; k < 100; ++k)
      for (int j = 50; j < 150; ++j)
        for (int i = 50; i < 150; ++i) big.labels[big.index(i, j, k)] = 1;
    big.materials = {{1, "tissue", {{0.1, 0.8, 0.1}}}};
    view.setVolume(big);
    QTRY_VERIFY_WITH_TIMEOUT(!view.isPreparingInput(), 60000);
    QCOMPARE(view.inputStride(), 2);
    QVERIFY(view.inputTriangleCount() > 100);
    const int green = pixelsLike(view.grabRenderImage(), big.materials[0].color);
    QVERIFY(green > 500);
    // A run's snapshot (red and blue particles) replaces the label surfaces.
    view.showSnapshot(makeSnapshot(200, 1));
    view.renderNow();
    QCOMPARE(view.content(), qFEMesherPreviewView::Content::Preview);
    QVERIFY(pixelsLike(view.grabRenderImage(), big.materials[0].color) < green / 4);
  }

  void largeMeshKeepsTheEventLoopResponsive() {
    // Issue 15: a mesh of over 500 k tets on screen, then what a re-run does to the view (clipping
    // off, material colours, a stream of live snapshots, the new result). A 10 ms timer measures
    // the longest gap between event-loop ticks; the bound is generous (behaviour, not speed).
    qFEMesherPreviewView view;
    view.resize(800, 600);
    view.show();
    QVERIFY(QTest::qWaitForWindowExposed(&view));
    const int n = 47;
    auto mesh = std::make_shared<TetMesh>(makeBlockMesh(n, 1.0));
    QVERIFY(mesh->tets.size() >= 500000);
    QElapsedTimer clock;
    clock.start();
    qint64 last = 0, worst = 0;
    QTimer tick;
    tick.setInterval(10);
    connect(&tick, &QTimer::timeout, [&] {
      const qint64 now = clock.elapsed();
      worst = std::max(worst, now - last);
      last = now;
    });
    auto restartProbe = [&] {
      last = clock.elapsed();
      worst = 0;
    };
    tick.start();
    auto shown = [&] {
      return view.content() == qFEMesherPreviewView::Content::Mesh && !view.isPreparingMesh();
    };

    // Showing.
    restartProbe();
    QTimer::singleShot(0, &view, [&] { view.setMesh(mesh); });
    QTRY_VERIFY_WITH_TIMEOUT(shown(), 120000);
    QTest::qWait(100);
    const qint64 showGap = worst;
    QVERIFY(view.isSurfaceOnly());
    // Boundary (6 sides of n x n squares) and the interface at x = n/2, two triangles a square.
    QCOMPARE(view.displayedCellCount(), size_t(7 * 2 * n * n));
    const QImage img = view.grabRenderImage();
    QVERIFY(pixelsLike(img, mesh->materials[0].color) > 500);
    QVERIFY(pixelsLike(img, mesh->materials[1].color) > 500);
    // Clipping the surfaces keeps whole triangles on one side.
    view.setClipping(true, 0, 0.5);
    view.renderNow();
    QVERIFY(view.displayedCellCount() > 0);
    QVERIFY(view.displayedCellCount() < size_t(7 * 2 * n * n));
    view.setColorBy(qFEMesherPreviewView::ColorBy::MinDihedral);
    QVERIFY(view.grabRenderImage() != img);

    // Re-running: clipping off, material colours, snapshots, then the new (large) result.
    restartProbe();
    QTimer::singleShot(0, &view, [&] {
      view.setClipping(false);
      view.setColorBy(qFEMesherPreviewView::ColorBy::Material);
    });
    view.setMinRedrawInterval(50);
    for (int i = 1; i <= 20; ++i) {
      view.showSnapshot(makeSnapshot(20000, i));
      QTest::qWait(20);
    }
    QTRY_VERIFY_WITH_TIMEOUT(view.content() == qFEMesherPreviewView::Content::Preview, 10000);
    auto second = std::make_shared<TetMesh>(*mesh);
    for (auto& l : second->tetLabels) l = 3 - l;  // the materials swap sides
    QTimer::singleShot(0, &view, [&] { view.setMesh(second); });
    QTRY_VERIFY_WITH_TIMEOUT(shown(), 120000);
    QTest::qWait(100);
    const qint64 rerunGap = worst;
    qInfo("longest event-loop gap with %zu tets: %lld ms while showing, %lld ms while re-running",
          mesh->tets.size(), showGap, rerunGap);
    QVERIFY2(showGap < 2000, qPrintable(QString("the GUI froze %1 ms showing the mesh").arg(showGap)));
    QVERIFY2(rerunGap < 2000, qPrintable(QString("the GUI froze %1 ms re-running").arg(rerunGap)));
    // A mesh replaced while its surfaces are built is dropped: the small one stays.
    view.setMesh(mesh);
    QVERIFY(view.isPreparingMesh());
    auto small = std::make_shared<TetMesh>(makeBlockMesh(6, 2.0));
    view.setMesh(small);
    QVERIFY(!view.isPreparingMesh());
    QTest::qWait(3000);
    QVERIFY(!view.isSurfaceOnly());
    QCOMPARE(view.displayedCellCount(), small->tets.size());
  }
};

int main(int argc, char* argv[]) {
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QApplication app(argc, argv);
  PreviewViewTest test;
  return QTest::qExec(&test, argc, argv);
}
#include "test_PreviewView.moc"
