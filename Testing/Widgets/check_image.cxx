// SPDX-License-Identifier: GPL-3.0-or-later
// FEMesherImageCheck [--labels 1,2,3] PNG...: fails unless every image exists, is at least
// 200x150 and is not blank (more than 64 distinct colours). With --labels, the images that
// follow must also show each label's default material colour (same chromaticity, any shading)
// in at least 3000 pixels (more than the table swatches and the legend): the mesh is really drawn, coloured by material.
#include <femesher/Types.h>

#include <QCoreApplication>
#include <QImage>
#include <QSet>
#include <QStringList>

#include <femesher/Phantom.h>

#include <cmath>
#include <cstdio>

namespace {
constexpr int kMinPixels = 3000;
int pixelsLike(const QImage& img, const std::array<double, 3>& c) {
  const double cs = c[0] + c[1] + c[2];
  int n = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const QColor p = img.pixelColor(x, y);
      const double s = p.redF() + p.greenF() + p.blueF();
      if (s < 0.3) continue;
      if (std::abs(p.redF() / s - c[0] / cs) < 0.03 && std::abs(p.greenF() / s - c[1] / cs) < 0.03 &&
          std::abs(p.blueF() / s - c[2] / cs) < 0.03)
        ++n;
    }
  return n;
}
}  // namespace

int main(int argc, char* argv[]) {
  QCoreApplication app(argc, argv);
  if (argc < 2) {
    std::fprintf(stderr, "usage: FEMesherImageCheck [--labels 1,2,...] IMAGE.png...\n");
    return 2;
  }
  int failures = 0;
  std::vector<int> labels;
  bool phantomColours = false;
  for (int i = 1; i < argc; ++i) {
    if (QString::fromLocal8Bit(argv[i]) == QLatin1String("--phantom")) {
      phantomColours = true;  // the sample's own material colours (from its .nrrd)
      continue;
    }
    if (QString::fromLocal8Bit(argv[i]) == QLatin1String("--labels") && i + 1 < argc) {
      labels.clear();
      for (const QString& l : QString::fromLocal8Bit(argv[++i]).split(',')) labels.push_back(l.toInt());
      continue;
    }
    const QImage img(QString::fromLocal8Bit(argv[i]));
    if (img.isNull()) {
      std::fprintf(stderr, "FAIL %s: missing or unreadable\n", argv[i]);
      ++failures;
      continue;
    }
    QSet<QRgb> colours;
    for (int y = 0; y < img.height(); y += 2)
      for (int x = 0; x < img.width(); x += 2) colours.insert(img.pixel(x, y) & 0xffffff);
    const bool big = img.width() >= 200 && img.height() >= 150;
    const bool varied = colours.size() > 64;
    std::printf("%s %s: %dx%d, %d distinct colours\n", big && varied ? "ok  " : "FAIL", argv[i],
                img.width(), img.height(), int(colours.size()));
    if (!big || !varied) ++failures;
    for (int l : labels) {
      std::array<double, 3> colour = femesher::defaultLabelColor(l);
      if (phantomColours)
        if (const femesher::Material* m = femesher::findMaterial(femesher::makePhantom().materials, l))
          colour = m->color;
      const int n = pixelsLike(img, colour);
      std::printf("     label %d colour: %d pixels%s\n", l, n, n >= kMinPixels ? "" : "  <- FAIL");
      if (n < kMinPixels) ++failures;
    }
  }
  return failures == 0 ? 0 : 1;
}
