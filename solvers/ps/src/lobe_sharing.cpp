#include "lobe_sharing.h"

#include "per_pixel_fits.h"

#include <omp.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <limits>
#include <memory>
#include <unordered_map>

namespace photorig::solvers::ps::internal {
namespace {

// Step 5 counts a region glossy only with at least this many confidently
// glossy pixels (the median of 16 is within about a third of a standard
// deviation of their spread).
constexpr std::size_t kMinPooledLobes = 16;
// Step 5 pools each pixel's lobe from this many of its region's confidently
// glossy pixels, the nearest to it (all, in a region with fewer).
constexpr std::size_t kPooledLobes = 32;
// Step 5 tests a glossy region's shape on about this many of the pixels it
// offers its lobe to (every 8th at least): the test's threshold is then
// within 14 % of its expectation, against a sum several times that where a
// GGX lobe is fitted as Blinn-Phong, and the test costs a few per cent of a
// glossy object's time.
constexpr std::size_t kShapeTestPixels = 1024;
// Steps 5 and 6 hand their pixels to the threads this many at a time: a few
// lane batches, so a chunk's overhead is small beside its fits.
constexpr std::size_t kPassChunk = 256;

// Step 5's lobe for a pixel of a region whose pixels reject one shared shape
// (ModelLadder::RejectsSharedShape): the medians of rho_s and e over the
// kPooledLobes confidently glossy pixels of its region nearest to it. Where
// the object's lobe is not Blinn-Phong, its best Blinn-Phong exponent varies
// over the object (a GGX lobe's long tails read as a broader lobe on the
// pixels that see only them, at the rim of a sphere), so the nearest
// confident pixels say more than the region's median. Nearest means by
// distance, ties to the lower pixel index, so the answer does not depend on
// the order the threads found them in. Where the glossy pixels are dense
// (most pixels of such a region kept a confident lobe) the offsets of a disc,
// walked in that order, find them after a few dozen lookups; elsewhere the
// glossy pixels, bucketed in square cells, are searched in rings around the
// pixel's cell until no pixel further out can be nearer.
class NearestLobes {
 public:
  // A glossy pixel seen: its squared distance, pixel index, and index into glossy_.
  struct Seen {
    int distance2, pixel, index;
    bool operator<(const Seen& other) const {
      return distance2 != other.distance2 ? distance2 < other.distance2 : pixel < other.pixel;
    }
  };

  // labels: CV_32S regions; glossy: confident pixels; in_region: how many of
  // them each region has.
  NearestLobes(const cv::Mat& labels, std::vector<GlossyPixel> glossy, std::vector<std::size_t> in_region)
      : rows_(labels.rows),
        cols_(labels.cols),
        cell_cols_((labels.cols + kCell - 1) / kCell),
        cell_rows_((labels.rows + kCell - 1) / kCell),
        label_(labels.ptr<int>()),
        in_region_(std::move(in_region)),
        cell_start_(static_cast<std::size_t>(cell_cols_) * cell_rows_ + 1, 0),
        glossy_index_(labels.total(), -1) {
    std::sort(glossy.begin(), glossy.end(), [this](const GlossyPixel& a, const GlossyPixel& b) {
      const int ca = Cell(a.pixel), cb = Cell(b.pixel);
      return ca != cb ? ca < cb : a.pixel < b.pixel;
    });
    for (const GlossyPixel& g : glossy) ++cell_start_[Cell(g.pixel) + 1];
    for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
    for (std::size_t i = 0; i < glossy.size(); ++i) glossy_index_[glossy[i].pixel] = static_cast<int>(i);
    glossy_ = std::move(glossy);
    // Every offset within kDiscRadius, in the order At ranks pixels: a pixel's
    // index differs from the centre's by dr * cols + dc, so ties go by that.
    for (int dr = -kDiscRadius; dr <= kDiscRadius; ++dr)
      for (int dc = -kDiscRadius; dc <= kDiscRadius; ++dc)
        if (dr * dr + dc * dc <= kDiscRadius * kDiscRadius) disc_.push_back({dr * dr + dc * dc, dr, dc});
    std::sort(disc_.begin(), disc_.end(), [this](const Offset& a, const Offset& b) {
      return a.distance2 != b.distance2 ? a.distance2 < b.distance2 : a.dr * cols_ + a.dc < b.dr * cols_ + b.dc;
    });
  }

  // near: scratch.
  SharedLobe At(int pixel, std::vector<Seen>* near) const {
    const int row = pixel / cols_, col = pixel % cols_;
    near->clear();
    // The disc holds every pixel within its radius, so the first kPooledLobes
    // found in its order are the nearest (any pixel outside is further).
    for (const Offset& o : disc_) {
      const int r = row + o.dr, c = col + o.dc;
      if (r < 0 || r >= rows_ || c < 0 || c >= cols_) continue;
      const int q = pixel + o.dr * cols_ + o.dc;
      if (glossy_index_[q] < 0 || label_[q] != label_[pixel]) continue;
      near->push_back({o.distance2, q, glossy_index_[q]});
      if (near->size() == kPooledLobes) return Medians(*near);
    }
    near->clear();
    const int cell_row = row / kCell, cell_col = col / kCell;
    const int rings = std::max(cell_rows_, cell_cols_);
    const std::size_t in_region = in_region_[label_[pixel]];
    // Once kPooledLobes are seen, the furthest of the nearest kPooledLobes: a
    // cell further than that holds none nearer.
    int bound = std::numeric_limits<int>::max();
    for (int ring = 0; ring < rings && near->size() < in_region; ++ring) {
      for (int r = cell_row - ring; r <= cell_row + ring; ++r) {
        if (r < 0 || r >= cell_rows_) continue;
        // The ring's top and bottom rows whole, its sides one cell each.
        const int step = r == cell_row - ring || r == cell_row + ring ? 1 : std::max(1, 2 * ring);
        for (int c = cell_col - ring; c <= cell_col + ring; c += step) {
          if (c < 0 || c >= cell_cols_ || CellDistance2(row, col, r, c) > bound) continue;
          for (int i = cell_start_[r * cell_cols_ + c]; i < cell_start_[r * cell_cols_ + c + 1]; ++i) {
            const int q = glossy_[i].pixel;
            if (label_[q] != label_[pixel]) continue;
            const int dr = q / cols_ - row, dc = q % cols_ - col;
            near->push_back({dr * dr + dc * dc, q, i});
          }
        }
      }
      // Every pixel outside the rings searched is at least ring * kCell away;
      // those beyond the nearest kPooledLobes can no longer enter them.
      if (near->size() >= kPooledLobes) {
        std::nth_element(near->begin(), near->begin() + (kPooledLobes - 1), near->end());
        near->resize(kPooledLobes);
        bound = std::max_element(near->begin(), near->end())->distance2;
        const int reach = ring * kCell;
        if (bound <= reach * reach) break;
      }
    }
    return Medians(*near);
  }

 private:
  static constexpr int kCell = 8;
  // Larger than a dense region needs (32 pixels lie within 3.2 pixels), small
  // enough that a sparse one soon falls back to the rings.
  static constexpr int kDiscRadius = 6;
  struct Offset {
    int distance2, dr, dc;
  };
  int Cell(int pixel) const { return (pixel / cols_ / kCell) * cell_cols_ + (pixel % cols_) / kCell; }
  // The squared distance from pixel (row, col) to the nearest pixel of cell (cell_row, cell_col).
  static int CellDistance2(int row, int col, int cell_row, int cell_col) {
    const int dr = std::max({0, cell_row * kCell - row, row - (cell_row * kCell + kCell - 1)});
    const int dc = std::max({0, cell_col * kCell - col, col - (cell_col * kCell + kCell - 1)});
    return dr * dr + dc * dc;
  }

  // The medians of rho_s and e over the nearest kPooledLobes of `seen` (all, if fewer).
  SharedLobe Medians(std::vector<Seen>& seen) const {
    const std::size_t pooled = std::min(seen.size(), kPooledLobes);
    if (pooled == 0) return {};
    std::nth_element(seen.begin(), seen.begin() + (pooled - 1), seen.end());
    float specular[kPooledLobes], exponent[kPooledLobes];
    for (std::size_t i = 0; i < pooled; ++i) {
      const GlossyPixel& g = glossy_[seen[i].index];
      specular[i] = g.specular_albedo, exponent[i] = g.exponent;
    }
    return {MedianOf(std::span(specular, pooled)), MedianOf(std::span(exponent, pooled))};
  }

  int rows_, cols_, cell_cols_, cell_rows_;
  const int* label_;
  std::vector<std::size_t> in_region_;
  std::vector<int> cell_start_;  // glossy_[cell_start_[c], cell_start_[c + 1]) lie in cell c
  std::vector<GlossyPixel> glossy_;
  std::vector<int> glossy_index_;  // per pixel, its index into glossy_ (-1: not glossy)
  std::vector<Offset> disc_;
};

// An int per pixel, 0 where none was set. Hashed where few pixels are set
// (a matte scene's floods touch a few thousand), a plain array where floods
// may cover much of the image: hashing a glossy object's every pixel costs a
// node allocation each, a tenth of shiny `auto`'s time.
class PixelInts {
 public:
  PixelInts(std::size_t pixels, bool dense) {
    if (dense) dense_.assign(pixels, 0);
  }
  int Get(int p) const {
    if (!dense_.empty()) return dense_[p];
    const auto found = sparse_.find(p);
    return found == sparse_.end() ? 0 : found->second;
  }
  int& At(int p) { return dense_.empty() ? sparse_[p] : dense_[p]; }

 private:
  std::vector<int> dense_;
  std::unordered_map<int, int> sparse_;
};

}  // namespace

// No region holds more glossy pixels than there are, so a region past
// glossy.size() / fraction pixels cannot be glossy: a flood from each glossy
// pixel stops there. The answer does not depend on the order of the floods:
// a region small enough is flooded whole by its first, and every flood in a
// region too big stops or meets an earlier one.
bool AnyRegionCouldBeGlossy(const cv::Mat& flags, std::span<const GlossyPixel> glossy, double fraction) {
  const int rows = flags.rows, cols = flags.cols;
  const std::uint8_t* flag = flags.ptr<std::uint8_t>();
  auto solved = [&](int p) { return flag[p] == static_cast<std::uint8_t>(PixelFlag::kSolved); };
  std::size_t glossy_solved = 0;
  for (const GlossyPixel& g : glossy) glossy_solved += solved(g.pixel);
  if (glossy_solved < kMinPooledLobes) return false;
  const double max_area = static_cast<double>(glossy_solved) / fraction;
  const std::size_t pixels = flags.total();
  const bool dense = max_area >= static_cast<double>(pixels) / 32.0;
  PixelInts glossy_at(pixels, dense);  // pixel -> its entries in `glossy`, as ShareLobes counts them
  for (const GlossyPixel& g : glossy)
    if (solved(g.pixel)) ++glossy_at.At(g.pixel);
  PixelInts flood_of(pixels, dense);  // pixel -> the flood that reached it (from 1)
  std::vector<int> front;
  int flood = 0;
  for (const GlossyPixel& g : glossy) {
    const int start = g.pixel;
    if (!solved(start) || flood_of.Get(start) != 0) continue;  // in a region already looked at
    ++flood;
    flood_of.At(start) = flood;
    front.assign(1, start);
    std::size_t area = 1, in_region = 0;
    bool too_big = false;
    while (!front.empty() && !too_big) {
      const int p = front.back();
      front.pop_back();
      in_region += static_cast<std::size_t>(glossy_at.Get(p));
      const int r = p / cols, c = p % cols;
      for (int dr = -1; dr <= 1 && !too_big; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc, q = rr * cols + cc;
          if (rr < 0 || rr >= rows || cc < 0 || cc >= cols || !solved(q)) continue;
          int& mark = flood_of.At(q);
          // A pixel of an earlier flood: that flood stopped short, so this is its too-big region.
          if (mark != 0 && mark != flood) too_big = true;
          if (mark != 0) continue;
          mark = flood;
          front.push_back(q);
          too_big = ++area > max_area;
          if (too_big) break;
        }
    }
    if (!too_big && in_region >= kMinPooledLobes && in_region >= fraction * static_cast<double>(area)) return true;
  }
  return false;
}

PixelFit FitInMap(const NormalMap& map, int p) {
  PixelFit fit;
  fit.ok = true;
  const cv::Vec3f n = map.normals.ptr<cv::Vec3f>()[p];
  fit.normal = Eigen::Vector3d(n[0], n[1], n[2]);
  fit.albedo = map.albedo.ptr<float>()[p];
  fit.used = map.usable_lights.ptr<std::uint16_t>()[p];
  fit.model = static_cast<PixelModel>(map.model.ptr<std::uint8_t>()[p]);
  const cv::Vec2f lobe = map.specular.ptr<cv::Vec2f>()[p];
  fit.specular_albedo = lobe[0];
  fit.exponent = lobe[1];
  return fit;
}

namespace {

// The parameters of a fit the map holds as `model` (held: a lobe step 5 held).
int KeptParameters(PixelModel model, bool held) {
  switch (model) {
    case PixelModel::kBlinnPhong: return held ? kSharedLobeParameters : kBlinnPhongParameters;
    case PixelModel::kGgx: return kGgxParameters;
    case PixelModel::kLowFrequency: return kLowFrequencyParameters;
    default: return 3;
  }
}

}  // namespace

PixelFit FitInMapWithChi2(const NormalMap& map, int p, bool held) {
  PixelFit fit = FitInMap(map, p);
  fit.parameters = KeptParameters(fit.model, held);
  const double confidence = map.confidence.ptr<float>()[p];
  fit.chi2 = fit.Dof() > 0 && confidence > 0.0 ? fit.Dof() / std::min(confidence, 1.0) : 0.0;
  return fit;
}

std::vector<std::uint8_t> ShareLobes(const ModelLadder& ladder, double glossy_region_fraction, const NormalMap& map,
                                     std::vector<GlossyPixel> glossy, int threads, const LobeSharingFits& fits) {
  // No region can be glossy: a matte scene stops here, before any pass over
  // the image. Where the floods' bound reaches the image's size, labelling
  // it costs no more and answers the same.
  const bool floods_cheaper = static_cast<double>(glossy.size()) / glossy_region_fraction < map.flags.total();
  if (floods_cheaper && !AnyRegionCouldBeGlossy(map.flags, glossy, glossy_region_fraction)) return {};
  const cv::Mat solved = map.flags == static_cast<int>(PixelFlag::kSolved);
  cv::Mat labels, stats, centroids;
  const int regions = cv::connectedComponentsWithStats(solved, labels, stats, centroids, 8, CV_32S);
  const int* label = labels.ptr<int>();
  // Sized before they fill: a glossy object's lists run to megabytes, and
  // growing them by doubling touches each page twice (fresh pages cost a
  // fault each, on a virtual machine about 10 us).
  std::vector<std::size_t> glossy_in(regions, 0), own_in(regions, 0);
  for (const GlossyPixel& g : glossy) ++glossy_in[label[g.pixel]], own_in[label[g.pixel]] += !g.held;
  std::vector<std::vector<float>> specular(regions), exponent(regions);
  for (int r = 0; r < regions; ++r) specular[r].reserve(own_in[r]), exponent[r].reserve(own_in[r]);
  for (const GlossyPixel& g : glossy) {
    if (g.held) continue;
    specular[label[g.pixel]].push_back(g.specular_albedo);
    exponent[label[g.pixel]].push_back(g.exponent);
  }
  // Label 0 is the background (pixels not solved).
  std::vector<SharedLobe> region_lobe(regions);
  bool any_glossy = false;
  for (int r = 1; r < regions; ++r) {
    const double area = stats.at<int>(r, cv::CC_STAT_AREA);
    if (exponent[r].empty() || glossy_in[r] < kMinPooledLobes || glossy_in[r] < glossy_region_fraction * area) continue;
    region_lobe[r] = {MedianOf(specular[r]), MedianOf(exponent[r])};
    any_glossy = true;
  }
  if (!any_glossy) return {};
  fits.begin();
  auto kept_without_lobe = [](std::uint8_t model) {
    return model == static_cast<std::uint8_t>(PixelModel::kLambertian) ||
           model == static_cast<std::uint8_t>(PixelModel::kTrimmed);
  };
  const std::uint8_t* model = map.model.ptr<std::uint8_t>();
  const int pixels = labels.rows * labels.cols;
  auto offers_lobe = [&](int p) { return region_lobe[label[p]].exponent > 0.0 && kept_without_lobe(model[p]); };
  std::size_t offers = 0;
  for (int p = 0; p < pixels; ++p) offers += offers_lobe(p);
  std::vector<SharedLobeItem> items;
  items.reserve(offers);
  for (int p = 0; p < pixels; ++p) {
    if (offers_lobe(p)) items.push_back({p, label[p], region_lobe[label[p]], false});
  }
  // Each glossy region's shape, tested on a sample of its pixels with its lobe and their own.
  std::vector<SharedLobeItem> sample;
  const std::size_t stride = std::max<std::size_t>(8, items.size() / kShapeTestPixels);
  for (std::size_t i = 0; i < items.size(); i += stride) {
    sample.push_back(items[i]);
    sample.back().test_shape = true;
  }
  std::vector<std::vector<SharedShapeTest>> tests(threads, std::vector<SharedShapeTest>(regions));
  // Chunks handed out as threads come free: pixels' fits differ in cost
  // (a GGX fit several times a held lobe's), and halves of the list leave
  // one thread idle for a third of the pass. A pixel's answer does not
  // depend on which thread fits it or on the pixels beside it in the lanes.
  auto in_parallel = [threads](std::size_t count, const auto& run) {
    std::atomic<std::size_t> next{0};
#pragma omp parallel num_threads(threads)
    {
      const int thread = omp_get_thread_num();
      for (std::size_t begin; (begin = next.fetch_add(kPassChunk)) < count;)
        run(thread, begin, std::min(count, begin + kPassChunk));
    }
  };
  // The sample in halves, one per thread: each thread's test sums in a
  // fixed order, so the verdict is the same on every run.
  auto halves = [threads](std::size_t count, const auto& run) {
#pragma omp parallel num_threads(threads)
    {
      const std::size_t thread = omp_get_thread_num(), team = omp_get_num_threads();
      run(static_cast<int>(thread), count * thread / team, count * (thread + 1) / team);
    }
  };
  halves(sample.size(), [&](int thread, std::size_t begin, std::size_t end) {
    fits.share(thread, std::span(sample).subspan(begin, end - begin), &tests[thread]);
  });
  auto region_test = [&](int r) {
    SharedShapeTest test;
    for (const std::vector<SharedShapeTest>& thread_tests : tests) {
      test.chi2_gain += thread_tests[r].chi2_gain;
      test.pixels += thread_tests[r].pixels;
      test.own_lobes += thread_tests[r].own_lobes;
      test.own_lobes_ggx += thread_tests[r].own_lobes_ggx;
    }
    return test;
  };
  // A glossy region the test does not reject is tested on its own lobes
  // (SharedShapeTest): up to kShapeTestPixels of them, spread evenly in
  // raster order whatever the threads did. Its pixels offered the region's
  // lobe are those whose samples cannot tell a lobe apart, and a metal has
  // none the held lobe explains (every pixel's samples see the lobe).
  std::vector<std::vector<int>> own_lobes(regions);
  for (const GlossyPixel& g : glossy)
    if (!g.held && region_lobe[label[g.pixel]].exponent > 0.0) own_lobes[label[g.pixel]].push_back(g.pixel);
  for (int r = 1; r < regions; ++r) {
    if (own_lobes[r].empty() || ladder.RejectsSharedShape(region_test(r))) continue;
    std::vector<int>& own = own_lobes[r];
    std::sort(own.begin(), own.end());
    std::vector<int> tested;
    const std::size_t count = std::min(own.size(), kShapeTestPixels);
    for (std::size_t i = 0; i < count; ++i) tested.push_back(own[i * own.size() / count]);
    halves(tested.size(), [&](int thread, std::size_t begin, std::size_t end) {
      fits.offer_ggx(thread, std::span(tested).subspan(begin, end - begin), &tests[thread][r]);
    });
  }
  std::vector<std::uint8_t> rejects(regions, 0);
  bool any_rejects = false;
  for (int r = 1; r < regions; ++r) {
    rejects[r] = ladder.RejectsSharedShape(region_test(r));
    any_rejects = any_rejects || rejects[r];
  }
  std::unique_ptr<NearestLobes> nearest;
  if (any_rejects) {
    std::erase_if(glossy, [](const GlossyPixel& g) { return g.held; });
    if (fits.own_lobes) {
      for (const GlossyPixel& g : fits.own_lobes([&](int p) { return rejects[label[p]] != 0; })) {
        glossy.push_back(g);
        ++own_in[label[g.pixel]];
      }
    }
    nearest = std::make_unique<NearestLobes>(labels, std::move(glossy), std::move(own_in));
  }
  in_parallel(items.size(), [&](int thread, std::size_t begin, std::size_t end) {
    std::vector<NearestLobes::Seen> near;
    for (std::size_t i = begin; i < end; ++i)
      if (rejects[items[i].region]) items[i].lobe = nearest->At(items[i].pixel, &near);
    fits.share(thread, std::span(items).subspan(begin, end - begin), nullptr);
  });
  if (!any_rejects) return {};
  // Step 6: where the lobe is not Blinn-Phong, each pixel of the region is offered a GGX lobe of its own.
  std::vector<std::uint8_t> region_rejects(pixels, 0);
  std::vector<int> offered;
  for (int p = 0; p < pixels; ++p) {
    if (!rejects[label[p]]) continue;
    region_rejects[p] = 1;
    if (kept_without_lobe(model[p]) || model[p] == static_cast<std::uint8_t>(PixelModel::kBlinnPhong)) offered.push_back(p);
  }
  in_parallel(offered.size(), [&](int thread, std::size_t begin, std::size_t end) {
    fits.offer_ggx(thread, std::span(offered).subspan(begin, end - begin), nullptr);
  });
  return region_rejects;
}

namespace {

// Every problem's lobe fit, solutions[i] answering problems[i].
std::vector<LobeSolution> FitEach(LobeLaneFitter& fitter, std::span<const LobeProblem> problems) {
  std::vector<LobeSolution> solutions(problems.size());
  if (!problems.empty()) fitter.Fit(problems, solutions);
  return solutions;
}

}  // namespace

void ClimbSharedLobes(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<SharingCandidate> batch,
                      const std::function<void(const SharingCandidate&, const PixelFit& chosen)>& done) {
  std::vector<LobeProblem> problems;
  for (const SharingCandidate& candidate : batch) {
    LobeProblem& problem = problems.emplace_back(candidate.problem);
    problem.start_normal = candidate.kept.normal, problem.start_albedo = candidate.kept.albedo;
    problem.shared_specular_albedo = candidate.item->lobe.specular_albedo;
    problem.shared_exponent = candidate.item->lobe.exponent;
  }
  const std::vector<LobeSolution> held = FitEach(fitter, problems);
  for (std::size_t i = 0; i < batch.size(); ++i) {
    SharingCandidate& candidate = batch[i];
    candidate.lobe = LobeFitFrom(held[i], candidate.lambertian.used, PixelModel::kBlinnPhong);
    candidate.lobe.parameters = kSharedLobeParameters;
    candidate.lobe_fitted = true;
  }
  ClimbFromHeldLobes(ladder, fitter, batch, done);
}

void ClimbFromHeldLobes(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<SharingCandidate> batch,
                        const std::function<void(const SharingCandidate&, const PixelFit& chosen)>& done) {
  std::vector<LobeProblem> problems;
  std::vector<std::size_t> owning;  // of `batch`: those the ladder asks for their own lobe
  for (std::size_t i = 0; i < batch.size(); ++i) {
    SharingCandidate& candidate = batch[i];
    const LadderStep step = ladder.NextWithSharedLobe(candidate.Fits());
    if (step.action == LadderStep::Action::kKeep) {
      done(candidate, *step.keep);
      continue;
    }
    owning.push_back(i);  // kFitOwnLobe
    LobeProblem& problem = problems.emplace_back(candidate.problem);
    problem.start_normal = step.start->normal, problem.start_albedo = step.start->albedo;
  }
  const std::vector<LobeSolution> own = FitEach(fitter, problems);
  for (std::size_t j = 0; j < owning.size(); ++j) {
    SharingCandidate& candidate = batch[owning[j]];
    candidate.own = LobeFitFrom(own[j], candidate.lambertian.used, PixelModel::kBlinnPhong);
    candidate.own_fitted = true;
    done(candidate, *ladder.NextWithSharedLobe(candidate.Fits()).keep);
  }
}

void ClimbGgx(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<GgxCandidate> batch,
              const std::function<void(const GgxCandidate&, const PixelFit& ggx)>& keep) {
  std::vector<LobeProblem> problems;
  for (const GgxCandidate& candidate : batch) {
    LobeProblem& problem = problems.emplace_back(candidate.problem);
    problem.start_normal = candidate.on_samples.normal, problem.start_albedo = candidate.on_samples.albedo;
  }
  const std::vector<LobeSolution> solutions = FitEach(fitter, problems);
  for (std::size_t i = 0; i < batch.size(); ++i) {
    const PixelFit ggx = LobeFitFrom(solutions[i], batch[i].on_samples.used, PixelModel::kGgx);
    if (ladder.NextWithGgx(GgxFits{&batch[i].on_samples, &ggx}).keep == &ggx) keep(batch[i], ggx);
  }
}

void TestGgx(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<GgxCandidate> batch, SharedShapeTest* test) {
  std::vector<PixelFit> kept_ggx(batch.size());  // not ok: the ladder kept no GGX fit
  ClimbGgx(ladder, fitter, batch,
           [&](const GgxCandidate& candidate, const PixelFit& ggx) { kept_ggx[&candidate - batch.data()] = ggx; });
  for (std::size_t i = 0; i < batch.size(); ++i)
    ladder.AddToShapeTest(GgxFits{&batch[i].on_samples, kept_ggx[i].ok ? &kept_ggx[i] : nullptr}, test);
}

namespace {

// Calls visit(p) for every solved pixel of `map` that kept a lobe, in
// raster order. A matte scene has a few per thousand pixels: blocks without
// one are passed over on a vector compare of their models, where the
// branches per pixel cost a tenth of matte `auto`'s time.
template <typename Visit>
void ForEachLobe(const NormalMap& map, const Visit& visit) {
  const std::uint8_t* flags = map.flags.ptr<std::uint8_t>();
  const std::uint8_t* model = map.model.ptr<std::uint8_t>();
  constexpr auto kBlinnPhong = static_cast<std::uint8_t>(PixelModel::kBlinnPhong);
  constexpr auto kGgx = static_cast<std::uint8_t>(PixelModel::kGgx);
  auto lobe = [&](int p) {
    return flags[p] == static_cast<std::uint8_t>(PixelFlag::kSolved) && (model[p] == kBlinnPhong || model[p] == kGgx);
  };
  const int pixels = static_cast<int>(map.flags.total());
  constexpr int kBlock = 64;
  int p = 0;
  for (; p + kBlock <= pixels; p += kBlock) {
    int lobes = 0;
#pragma omp simd reduction(+ : lobes)
    for (int j = 0; j < kBlock; ++j) lobes += (model[p + j] == kBlinnPhong) | (model[p + j] == kGgx);
    if (lobes == 0) continue;
    for (int j = 0; j < kBlock; ++j)
      if (lobe(p + j)) visit(p + j);
  }
  for (; p < pixels; ++p)
    if (lobe(p)) visit(p);
}

}  // namespace

std::vector<int> LowFrequencyCandidates(const ModelLadder& ladder, const NormalMap& map,
                                        const std::vector<std::uint8_t>& held, bool test_lobe_shift) {
  const std::uint16_t* used = map.usable_lights.ptr<std::uint16_t>();
  const float* confidence = map.confidence.ptr<float>();
  const std::uint8_t* model = map.model.ptr<std::uint8_t>();
  std::vector<int> candidates;
  auto offer = [&](int p) {
    const bool is_held = !held.empty() && held[p] != 0;
    const PixelFit kept = FitInMapWithChi2(map, p, is_held);
    LowFrequencyFits fits{&kept};
    fits.test_lobe_shift = test_lobe_shift;
    if (ladder.NextWithLowFrequency(fits).action == LadderStep::Action::kFitLowFrequency) candidates.push_back(p);
  };
  if (ladder.method() != Method::kAuto) {
    const std::uint8_t* flags = map.flags.ptr<std::uint8_t>();
    for (int p = 0; p < static_cast<int>(map.flags.total()); ++p)
      if (flags[p] == static_cast<std::uint8_t>(PixelFlag::kSolved)) offer(p);
    return candidates;
  }
  // `auto` looks only at lobes, and without the lobe-shift test only at one
  // that fails the adequacy test, as its confidence tells.
  ForEachLobe(map, [&](int p) {
    const bool is_held = !held.empty() && held[p] != 0;
    const int dof = used[p] - KeptParameters(static_cast<PixelModel>(model[p]), is_held);
    if (!test_lobe_shift && dof > 0 && confidence[p] >= ladder.AdequateConfidence(dof)) return;
    offer(p);
  });
  return candidates;
}

PixelFit ClimbLowFrequency(const ModelLadder& ladder, LowFrequencyFitter& fitter, const PixelFit& kept,
                           const LowFrequencyProblem& problem, const LowFrequencyOffer& offer, bool* fell_back,
                           LobeShiftTally* tally, LowFrequencyRule* rule) {
  int usable = 0;
  for (int k = 0; k < problem.lights; ++k) usable += problem.inverse_sigma[k] > 0.0;
  LowFrequencyFits fits{&kept};
  fits.region_rejects_shape = offer.region_rejects_shape;
  if (offer.region_rejects_shape && kept.model == PixelModel::kBlinnPhong) {
    fits.lobe_at_exponent_bound = kept.exponent <= offer.min_exponent;
    fits.lobe_term_chi2 = BlinnPhongTermChi2(kept, problem);
  }
  fits.test_lobe_shift = offer.test_lobe_shift;
  fits.spike_pins_normal = SpikePinsNormal(kept, problem, fitter.LeftOut(usable));
  const bool lobe = kept.model == PixelModel::kBlinnPhong || kept.model == PixelModel::kGgx;
  const bool test_shift = offer.test_lobe_shift && lobe;
  PixelFit low, judged;
  std::vector<double> predicted;
  for (;;) {
    const LadderStep step = ladder.NextWithLowFrequency(fits);
    if (step.action != LadderStep::Action::kFitLowFrequency) {
      *fell_back = step.fell_back;
      if (rule) *rule = step.low_frequency_rule;
      return *step.keep;
    }
    const LowFrequencySolution on_samples = fitter.Fit(problem);
    low = LowFrequencyFitFrom(on_samples);
    judged = KeptOnLights(kept, fitter.used_lights(), problem.wx, problem.wy, problem.wz, problem.stride, problem.view,
                          problem.observed, problem.inverse_sigma, test_shift ? &predicted : nullptr);
    fits.low_frequency = &low;
    fits.kept_on_samples = &judged;
    if (test_shift && on_samples.ok && judged.ok) {
      const Eigen::Vector2d offset = on_samples.tangents.transpose() * (kept.normal - on_samples.normal);
      fits.lobe_offset_chi2 = offset.dot(on_samples.normal_information * offset);
    }
    // Where the two normals agree within the noise the lobe stands whatever
    // the shift, and only a tally (the scene's sample) needs it measured.
    if (test_shift && on_samples.ok && judged.ok && (tally || ladder.LobeShifted(fits.lobe_offset_chi2))) {
      // The same fit of the lobe's prediction: where the lobe would put the
      // low-frequency normal, its bias on an exact lobe included.
      const LowFrequencySolution on_lobe = fitter.FitSameSamples(predicted);
      if (on_lobe.ok) {
        const Eigen::Vector2d shift = on_samples.tangents.transpose() * (on_lobe.normal - on_samples.normal);
        fits.lobe_shift_chi2 = shift.dot(on_samples.normal_information * shift);
        const Eigen::Vector2d bias = on_samples.tangents.transpose() * (on_lobe.normal - kept.normal);
        fits.lobe_bias_chi2 = bias.dot(on_samples.normal_information * bias);
        if (tally) {
          ++tally->tested;
          tally->shifted += ladder.LobeShifted(fits.lobe_shift_chi2);
        }
      }
    }
  }
}

LowFrequencyPlan PlanLowFrequency(const ModelLadder& ladder, const NormalMap& map, const std::vector<std::uint8_t>& held,
                                  bool glossy_region,
                                  const std::function<LobeShiftTally(std::span<const int> sample)>& climb_sample) {
  // Without a glossy region the scene's lobes are the noise's chance fits,
  // with no material to test (a matte scene pays nothing).
  if (!ladder.lobe_shift_test() || !glossy_region) return {LowFrequencyCandidates(ladder, map, held, false), false, {}};
  // The sample spread evenly over the lobes in raster order (the same
  // whatever the threads do); the candidates listed once, as the sample decides.
  std::vector<int> lobes;
  ForEachLobe(map, [&](int p) { lobes.push_back(p); });
  std::vector<int> sample;
  const std::size_t count = std::min<std::size_t>(kLobeShiftSample, lobes.size());
  for (std::size_t i = 0; i < count; ++i) sample.push_back(lobes[i * lobes.size() / count]);
  const LobeShiftTally tally = climb_sample(sample);
  const bool every_lobe = ladder.LobesFailShiftTest(tally.shifted, tally.tested);
  return {LowFrequencyCandidates(ladder, map, held, every_lobe), every_lobe, tally};
}

void CountRule(LowFrequencyRule rule, LowFrequencyRuleCounts* counts) {
  switch (rule) {
    case LowFrequencyRule::kLobeShifted: ++counts->lobe_shifted; break;
    case LowFrequencyRule::kExplainsApart: ++counts->explains_apart; break;
    case LowFrequencyRule::kRegionRejectsShape: ++counts->region_rejects_shape; break;
    case LowFrequencyRule::kStrongEvidence: ++counts->strong_evidence; break;
    case LowFrequencyRule::kNone: break;
  }
}

void LowFrequencyPlan::AddTo(SolverSummary* summary) const {
  summary->lobe_shift_sample_tested = static_cast<std::size_t>(sample.tested);
  summary->lobe_shift_sample_shifted = static_cast<std::size_t>(sample.shifted);
  summary->lobe_shift_every_lobe = test_lobe_shift;
}

}  // namespace photorig::solvers::ps::internal
