#include "tools/train_codebook/procedural_images.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

namespace ag {

namespace {

cv::Scalar RandomColour(cv::RNG& rng) {
  return cv::Scalar(rng.uniform(0, 256), rng.uniform(0, 256), rng.uniform(0, 256));
}

cv::Point RandomPoint(cv::RNG& rng, cv::Size size) {
  return {rng.uniform(0, size.width), rng.uniform(0, size.height)};
}

/// Smooth colour field: a few random values per side, bicubically enlarged.
cv::Mat SmoothField(cv::RNG& rng, cv::Size size, int cells) {
  cv::Mat small(cells, cells, CV_8UC3);
  rng.fill(small, cv::RNG::UNIFORM, 0, 256);
  cv::Mat field;
  cv::resize(small, field, size, 0, 0, cv::INTER_CUBIC);
  return field;
}

/// Fractal noise (octaves of smooth noise, halving amplitude): foliage,
/// gravel, grass-like texture.
cv::Mat FractalTexture(cv::RNG& rng, cv::Size size) {
  cv::Mat sum = cv::Mat::zeros(size, CV_32FC3);
  double amplitude = 1.0;
  for (int cell = rng.uniform(16, 64); cell >= 1; cell /= 2, amplitude *= 0.6) {
    cv::Mat small(std::max(1, size.height / cell), std::max(1, size.width / cell), CV_32FC3);
    rng.fill(small, cv::RNG::UNIFORM, -1.0, 1.0);
    cv::Mat octave;
    cv::resize(small, octave, size, 0, 0, cv::INTER_LINEAR);
    sum += amplitude * octave;
  }
  const cv::Scalar base = RandomColour(rng);
  cv::Mat texture;
  sum.convertTo(texture, CV_8UC3, rng.uniform(30.0, 90.0));
  cv::Mat out;
  cv::add(cv::Mat(size, CV_8UC3, base * 0.7), texture, out);
  return out;
}

/// Random texture: noise at a random scale, sharp (nearest) or smooth.
cv::Mat Texture(cv::RNG& rng, cv::Size size) {
  if (rng.uniform(0, 2)) return FractalTexture(rng, size);
  const int cell = rng.uniform(1, 12);
  cv::Mat small(std::max(1, size.height / cell), std::max(1, size.width / cell), CV_8UC3);
  rng.fill(small, cv::RNG::UNIFORM, 0, 256);
  cv::Mat texture;
  cv::resize(small, texture, size, 0, 0, rng.uniform(0, 2) ? cv::INTER_NEAREST : cv::INTER_LINEAR);
  return texture;
}

std::vector<cv::Point> RotatedRectangle(cv::RNG& rng, cv::Size size) {
  const cv::RotatedRect rect(
      cv::Point2f(RandomPoint(rng, size)),
      cv::Size2f(rng.uniform(8.0f, size.width / 3.0f), rng.uniform(8.0f, size.height / 3.0f)),
      rng.uniform(0.0f, 180.0f));
  cv::Point2f corners[4];
  rect.points(corners);
  return {corners[0], corners[1], corners[2], corners[3]};
}

void DrawShape(cv::Mat& image, cv::RNG& rng) {
  const cv::Size size = image.size();
  const cv::Scalar colour = RandomColour(rng);
  switch (rng.uniform(0, 8)) {
    case 0: {  // rotated filled rectangle
      const std::vector<cv::Point> poly = RotatedRectangle(rng, size);
      cv::fillConvexPoly(image, poly, colour, cv::LINE_AA);
      break;
    }
    case 1:  // ellipse
      cv::ellipse(image, RandomPoint(rng, size),
                  cv::Size(rng.uniform(4, size.width / 6), rng.uniform(4, size.height / 6)),
                  rng.uniform(0.0, 180.0), 0, 360, colour, -1, cv::LINE_AA);
      break;
    case 2: {  // random polygon (possibly concave)
      std::vector<cv::Point> poly;
      const cv::Point centre = RandomPoint(rng, size);
      const int n = rng.uniform(3, 8);
      const int radius = rng.uniform(10, std::max(11, std::min(size.width, size.height) / 4));
      for (int i = 0; i < n; ++i) {
        const double angle = 2 * CV_PI * i / n + rng.uniform(-0.3, 0.3);
        const double r = radius * rng.uniform(0.4, 1.0);
        poly.emplace_back(centre.x + static_cast<int>(r * std::cos(angle)),
                          centre.y + static_cast<int>(r * std::sin(angle)));
      }
      cv::fillPoly(image, std::vector<std::vector<cv::Point>>{poly}, colour, cv::LINE_AA);
      break;
    }
    case 3:  // line
      cv::line(image, RandomPoint(rng, size), RandomPoint(rng, size), colour, rng.uniform(1, 6),
               cv::LINE_AA);
      break;
    case 4: {  // checkerboard patch
      const int square = rng.uniform(4, 24);
      const int nx = rng.uniform(2, 8);
      const int ny = rng.uniform(2, 8);
      const cv::Point origin = RandomPoint(rng, size);
      const cv::Scalar other = RandomColour(rng);
      for (int y = 0; y < ny; ++y) {
        for (int x = 0; x < nx; ++x) {
          cv::rectangle(image,
                        cv::Rect(origin.x + x * square, origin.y + y * square, square, square),
                        (x + y) % 2 ? colour : other, -1);
        }
      }
      break;
    }
    case 5: {  // facade: a wall with a grid of windows
      const cv::Rect wall(RandomPoint(rng, size), cv::Size(rng.uniform(40, size.width / 2),
                                                           rng.uniform(40, size.height / 2)));
      cv::rectangle(image, wall, colour, -1);
      const int w = rng.uniform(4, 16);
      const int h = rng.uniform(4, 20);
      const int gap = rng.uniform(3, 12);
      const cv::Scalar glass = RandomColour(rng);
      for (int y = wall.y + gap; y + h < wall.y + wall.height; y += h + gap) {
        for (int x = wall.x + gap; x + w < wall.x + wall.width; x += w + gap) {
          cv::rectangle(image, cv::Rect(x, y, w, h), glass, -1);
        }
      }
      break;
    }
    case 6: {  // text
      std::string text;
      const int n = rng.uniform(2, 10);
      for (int i = 0; i < n; ++i) text += static_cast<char>(rng.uniform(33, 127));
      cv::putText(image, text, RandomPoint(rng, size), rng.uniform(0, 8), rng.uniform(0.4, 2.5),
                  colour, rng.uniform(1, 4), cv::LINE_AA);
      break;
    }
    default: {  // textured region in a random rectangle
      std::vector<cv::Point> poly = RotatedRectangle(rng, size);
      cv::Mat mask = cv::Mat::zeros(size, CV_8U);
      cv::fillConvexPoly(mask, poly, cv::Scalar(255));
      Texture(rng, size).copyTo(image, mask);
      break;
    }
  }
}

}  // namespace

cv::Mat MakeProceduralImage(cv::Size size, uint64_t seed) {
  cv::RNG rng(seed ^ 0x9e3779b97f4a7c15ULL);
  // Half of the images start from ground-like texture (an aerial view),
  // the others from a smooth colour field.
  cv::Mat image =
      rng.uniform(0, 2) ? FractalTexture(rng, size) : SmoothField(rng, size, rng.uniform(2, 9));
  const int shapes = rng.uniform(30, 120);
  for (int i = 0; i < shapes; ++i) DrawShape(image, rng);

  const double sigma = rng.uniform(0.0, 1.5);
  if (sigma > 0.3) cv::GaussianBlur(image, image, cv::Size(0, 0), sigma);
  cv::Mat noise(size, CV_16SC3);
  rng.fill(noise, cv::RNG::NORMAL, 0, rng.uniform(0.0, 8.0));
  cv::Mat noisy;
  image.convertTo(noisy, CV_16SC3, rng.uniform(0.6, 1.3), rng.uniform(-40.0, 40.0));
  noisy += noise;
  noisy.convertTo(image, CV_8UC3);  // saturates
  return image;
}

}  // namespace ag
