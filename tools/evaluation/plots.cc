#include "tools/evaluation/plots.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace ag {
namespace {

// A "nice" tick step (1, 2 or 5 times a power of ten) for a span.
double TickStep(double span, int target_ticks) {
  const double raw = span / std::max(target_ticks, 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10 * p;
}

std::string Format(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", std::abs(v) < 1e-12 ? 0.0 : v);
  return buf;
}

}  // namespace

void WritePlot(const std::string& path, const std::string& title, const std::string& x_label,
               const std::string& y_label, const std::vector<PlotSeries>& series, bool equal_aspect,
               int width, int height) {
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 80, right = 20, top = 50, bottom = 60;
  const cv::Rect area(left, top, width - left - right, height - top - bottom);
  double x0 = std::numeric_limits<double>::max(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const auto& s : series) {
    for (const auto& p : s.points) {
      if (!p.allFinite()) continue;
      x0 = std::min(x0, p.x());
      x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y());
      y1 = std::max(y1, p.y());
    }
  }
  if (x0 > x1) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  if (x1 - x0 < 1e-9) x0 -= 0.5, x1 += 0.5;
  if (y1 - y0 < 1e-9) y0 -= 0.5, y1 += 0.5;
  double sx = area.width / (x1 - x0);
  double sy = area.height / (y1 - y0);
  if (equal_aspect) {
    const double s = std::min(sx, sy);
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
    x0 = cx - 0.5 * area.width / s;
    x1 = cx + 0.5 * area.width / s;
    y0 = cy - 0.5 * area.height / s;
    y1 = cy + 0.5 * area.height / s;
    sx = sy = s;
  } else {
    const double pad = 0.05 * (y1 - y0);
    y0 -= pad;
    y1 += pad;
    sy = area.height / (y1 - y0);
  }
  auto to_px = [&](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(area.x + (p.x() - x0) * sx)),
                     static_cast<int>(std::lround(area.y + area.height - (p.y() - y0) * sy)));
  };
  const cv::Scalar grid(225, 225, 225), ink(40, 40, 40);
  const double xs = TickStep(x1 - x0, 8), ys = TickStep(y1 - y0, 8);
  for (double x = std::ceil(x0 / xs) * xs; x <= x1 + 1e-9; x += xs) {
    const cv::Point a = to_px({x, y0}), b = to_px({x, y1});
    cv::line(img, a, b, grid, 1);
    cv::putText(img, Format(x), {a.x - 12, area.y + area.height + 20}, cv::FONT_HERSHEY_SIMPLEX,
                0.45, ink, 1, cv::LINE_AA);
  }
  for (double y = std::ceil(y0 / ys) * ys; y <= y1 + 1e-9; y += ys) {
    const cv::Point a = to_px({x0, y}), b = to_px({x1, y});
    cv::line(img, a, b, grid, 1);
    cv::putText(img, Format(y), {8, a.y + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, ink, 1, cv::LINE_AA);
  }
  cv::putText(img, title, {left, 30}, cv::FONT_HERSHEY_SIMPLEX, 0.7, ink, 2, cv::LINE_AA);
  cv::putText(img, x_label, {area.x + area.width / 2 - 40, height - 15}, cv::FONT_HERSHEY_SIMPLEX,
              0.55, ink, 1, cv::LINE_AA);
  cv::putText(img, y_label, {8, top - 10}, cv::FONT_HERSHEY_SIMPLEX, 0.55, ink, 1, cv::LINE_AA);
  for (const auto& s : series) {
    const cv::Scalar colour(s.b, s.g, s.r);
    for (size_t i = 0; i < s.points.size(); ++i) {
      if (!s.points[i].allFinite()) continue;
      if (s.markers) {
        cv::circle(img, to_px(s.points[i]), 3, colour, cv::FILLED, cv::LINE_AA);
      } else if (i > 0 && s.points[i - 1].allFinite()) {
        cv::line(img, to_px(s.points[i - 1]), to_px(s.points[i]), colour, 2, cv::LINE_AA);
      }
    }
  }
  int ly = top + 20;
  for (const auto& s : series) {
    const cv::Scalar colour(s.b, s.g, s.r);
    cv::line(img, {area.x + area.width - 220, ly - 5}, {area.x + area.width - 190, ly - 5}, colour,
             3);
    cv::putText(img, s.label, {area.x + area.width - 180, ly}, cv::FONT_HERSHEY_SIMPLEX, 0.5, ink,
                1, cv::LINE_AA);
    ly += 22;
  }
  cv::rectangle(img, area, ink, 1);
  if (!cv::imwrite(path, img)) throw std::runtime_error("cannot write plot " + path);
}

}  // namespace ag
