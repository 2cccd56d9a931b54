#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace ag {

/// A named polyline for a plot, colour as BGR.
struct PlotSeries {
  std::string label;
  std::vector<Eigen::Vector2d> points;
  int b = 0, g = 0, r = 0;
  bool markers = false;  ///< draw points as dots instead of a line
};

/// Writes a PNG line plot with axes, ticks and a legend. `equal_aspect` keeps
/// metres equal on both axes (trajectories). Throws std::runtime_error if the
/// file cannot be written.
void WritePlot(const std::string& path, const std::string& title, const std::string& x_label,
               const std::string& y_label, const std::vector<PlotSeries>& series, bool equal_aspect,
               int width = 900, int height = 700);

}  // namespace ag
