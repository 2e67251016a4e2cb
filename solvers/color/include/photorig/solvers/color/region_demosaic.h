#pragma once
// Demosaicing that keeps each region's colours to itself. A bilinear demosaic
// fills a pixel's missing channels from the sites around it, on both sides of
// a paint edge, so every pixel along the edge holds a blend of two albedos
// that is neither paint. Given a label per pixel (a material map) the missing
// channels are taken from sites of the pixel's own label only; and since the
// labels near an edge are themselves uncertain, the raw sites settle them
// first: a pixel's own site measures one channel of its own paint without
// interpolation, and the paint whose nearby sites of that channel match it
// over every frame is the pixel's paint.

#include "photorig/solvers/core/summary.h"

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace photorig::solvers::color {

// Label of a pixel that belongs to no region (the background, or unknown).
inline constexpr std::uint8_t kNoRegion = 255;

// Bilinear demosaicing kept within regions (`regions`: CV_8U, the raw's
// size). A pixel's missing channel is the mean of that channel's sites in its
// 3 x 3 window that carry the pixel's own label, or in its 5 x 5 window when
// none in the 3 x 3 does. Where every site is of the pixel's label this is
// solvers::color::Demosaic's bilinear interpolation (the mean of the channel's sites
// in the 3 x 3 window; at the image's border, of those inside it); a pixel
// labelled kNoRegion, or with no site of its label within 5 x 5, is
// interpolated from every site in its 3 x 3 window. Linear in the raw values
// for fixed labels, so darks demosaiced with the same labels subtract
// exactly. `bgr` is CV_32FC3 (B, G, R): the means are not rounded.
solvers::core::Summary DemosaicWithinRegions(const cv::Mat& raw, const std::string& pattern, const cv::Mat& regions,
                                       cv::Mat* bgr);

// Settles the labels along the regions' edges from the raw frames. A pixel is
// contested when a site of its colour within its 5 x 5 window carries another
// label (kNoRegion pixels are neither contested nor evidence). For each label
// among those sites and each frame, the mismatch is
//   |own site - m| / (|own site| + |m| + floor_dn),
// m the mean of that label's sites of the pixel's colour in the window:
// nearby sites of the pixel's own paint differ from it by shading alone,
// another paint's by its albedo. Each frame counts at most 1, so the few
// frames where a sharp highlight crosses the window do not outvote the rest,
// and floor_dn (a few times the read noise) keeps unlit frames from counting
// noise as a difference. A contested pixel takes the label of least summed
// mismatch when that is under `switch_ratio` times its present label's and
// below it by more than `min_difference` per frame (a clear verdict: where
// two paints nearly agree in the pixel's channel, or the pixel matches both
// within noise, the first labels stand). Frames are added one at a time, so
// a long stack is never held in memory.
class RegionEdgeVote {
 public:
  struct Options {
    double floor_dn = 1.0;       // > 0; see above. Default 1 DN.
    double switch_ratio = 0.5;   // in (0, 1]. Default 0.5.
    double min_difference = 0.03;  // >= 0, mean per frame. Default 0.03 (paints 6 % apart in the channel).

    bool IsValid(std::string* why) const;
  };

  // Checks the options, the pattern and the labels (CV_8U); on failure
  // status() says why, every later call does nothing and Regions() returns
  // the labels unchanged.
  RegionEdgeVote(const std::string& pattern, const cv::Mat& regions, const Options& options);
  const solvers::core::Summary& status() const { return status_; }

  // One frame: raw values (CV_16U, CV_8U or CV_32F, the labels' size), dark
  // subtracted, and optionally where the sensor clipped (CV_8U, nonzero): a
  // pixel skips a frame in which its site or one of its window's sites of its
  // colour was clipped.
  solvers::core::Summary Add(const cv::Mat& raw, const cv::Mat& clipped = cv::Mat());

  // The labels with every clear verdict applied; `changed` (optional) counts them.
  cv::Mat Regions(int* changed = nullptr) const;
  int contested_pixels() const { return static_cast<int>(contested_.size()); }

 private:
  static constexpr int kMaxLabels = 4;  // distinct labels in one 5 x 5 window that are tracked
  struct Contested {
    int y = 0, x = 0;
    std::array<std::uint8_t, kMaxLabels> label{};
    std::array<double, kMaxLabels> mismatch{};
    int labels = 0;
    int frames = 0;  // frames that counted (none of its sites clipped)
  };
  solvers::core::Summary status_;
  cv::Mat regions_;
  Options options_;
  int site_channel_[2][2] = {{0, 0}, {0, 0}};
  std::vector<Contested> contested_;
};

}  // namespace photorig::solvers::color
