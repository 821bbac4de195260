#pragma once
// How the body outside the lungs moves (#31, #45; docs/voxels.md, "Around the lungs").
//
// The lungs slide along the pleura, and nothing else tears: the tissue around them (chest wall,
// mediastinum and heart, the abdomen under the diaphragm) follows the pleura's motion *across*
// it, so that nothing opens or overlaps there, and lets the lung slide *along* it: the only
// discontinuity is the tangential slide at the pleura. pneuma extends the normal part of each
// lung's surface motion smoothly into the body and fades it with the distance from the lungs:
//
//   u(x) = sum over lungs of  s_lung * E_lung(x) * exp(-d(x) / L(x)) * taper(x)
//
//   E_lung(x) = sum_v K(x - y_v) A_v (n_v . u_v) n_v  /  sum over all lungs' v of K(x - y_v) A_v
//
// (the diaphragm's vertices, and those off the lobes, contribute their whole motion, below, "Off
// the lobes"; docs/voxels.md; and E then gains one
// round of correction at the pleura, below, "At the pleura")
// with y_v, n_v, A_v and u_v a rest surface vertex, its outward normal, its area and its unit
// displacement; K a sum of Gaussians of sigma 12, 24, 48 and 96 mm weighted 1/sigma^5 (near the
// pleura the narrowest decides, so E is the local normal motion, blurred over about 12 mm; far
// away the wider ones take over, so E is defined and smooth everywhere); d(x) the distance to the
// nearest lung surface; L(x) blended from 40 mm (chest wall, mediastinum and heart) to 120 mm
// (the abdomen: the liver dome follows the diaphragm, the kidneys about 10 cm below move about
// half as far) by the diaphragm's share of the weights at x; and a taper to zero over the last
// 48 mm of the field's box (80 mm around the lungs, 200 mm below them). Between two lungs each
// point follows the nearer lung's face most: the heart and mediastinum move with the medial
// faces and, near it, the diaphragm. E, L and the fade are smooth on the scale of 12 mm, so the
// field has no bands and no tears; where the surface's motion is too sharp for a 12 mm blur, the
// run widens it (below), so that the field's gradient is bounded in the body.
//
// The narrowest blur. Where a lung's surface motion changes sharply (the diaphragm's or a
// recess tip's descent of 20-30 mm beside a chest wall that moves 1 mm across it), a 12 mm blur
// leaves |grad u| of 0.6 to 1 in the body below the lungs' bases. At |grad u| >= 1 the body can
// fold; and a deflation (the scan at end-inspiration) turns the same gradient into a compression,
// whose pull-back J = 1 / (1 - g) leaves [0.5, 2] already at g = 0.5 (a stretch reaches 2 only at
// g = 1). So the blur is chosen per run, as the deflation's smoothing is (model.h,
// field_for_deflation): the least sigma of a short ladder for which u, at `margin` (1.5) times
// each end of the breath, has |grad u| <= `steepest_allowed` (0.75; the spectral norm, the most
// any direction's length changes) on every node of the grid outside the lungs and a cell or more
// from their surface. At the run's own scales |grad u| <= 0.5 there: u is a contraction, so
// x -> x + u(x) is one-to-one and the fixed-point pull-back converges; every principal stretch
// lies in [0.5, 1.5]; a compression along one direction keeps the pull-back J <= 2; and no two
// points a voxel apart move more than half a voxel apart. A field that passes at 12 mm is kept
// as it was. The price of a wider blur: the body follows the pleura less closely across it.
// At the pleura. K's blur is an average, not an interpolant: where the followed motion changes
// within it (the diaphragm's full descent beside the costal face's normal part, at the
// costophrenic edges) the body at the pleura fell 20-30 % short of the lung's motion across it,
// a jump at the pleura that the tear check sees at 2 mm voxels (case004: the body under
// the left lung's anterior base descended 8.3 mm where the lung's boundary descended 10.5 mm).
// So the field gets `pleura_corrections` rounds (1) of successive correction (Barnes): at every
// vertex the shortfall of the body's motion across the pleura, n_v . (m_v - u(y_v)) n_v (only the
// normal part: along the pleura the lung slides; off the lobes, below, the whole of m_v - u(y_v)),
// is blurred by the same normalised K and added (faded as E is). The error across the pleura left
// by the blur shrinks to about its square; the field gets steeper near the pleura, and the
// narrowest blur's rule (above) judges the corrected field, so it stays a contraction where it
// judges. Tried, not kept (docs/voxels.md, "The body's pairs at 2 mm voxels"): the whole shortfall
// under the diaphragm too (the phantom's field then needs a 24 mm blur, not 16 mm, and falls
// further short across the pleura: 0.180 against 0.105), and two rounds (steeper than the rule
// allows even at the ladder's widest blur).
// Off the lobes. A surface made from a label map is closed where the lobes are not (the hilum's
// vessels and airways, holes filled in slices to reach genus 0; mesh/labels.h): there the mesh
// lies on tissue the label map does not call lung, and the voxel outputs move it with the lung
// (docs/voxels.md, "Around the lungs"). There is no pleura there to slide along (the lung's root
// is tethered to the mediastinum), so the body follows the whole of the surface's motion: w_v is
// the larger of the diaphragm's share and the vertex's share off the lobes, the depth along the
// inward normal at which the label map first shows the lung within a voxel (0 up to 1.5 mm, 1
// from 3 mm, a smooth step between). Measured (2 mm voxels): case008's 4 and 23 neighbour pairs
// at the right hilum (supine and upright, scan at end-inspiration), a 2.5 mm vertical slide
// across the flat face the filled hilum leaves, are gone.
// The field is precomputed per lung for s = 1 on a grid of `cell_m` (6 mm) and interpolated
// trilinearly; a frame's field is the lungs' scales times theirs. A voxel output asks it at tens of
// millions of points per time point: BodyMotion::Frame sums the lungs' grids with their scales
// once, so that each point costs one trilinear lookup (#50).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pneuma::model {

struct Model;

struct BodyMotionOptions {
  double wall_decay_m = 0.04;       // L beside the chest wall, the mediastinum and the heart
  double abdomen_decay_m = 0.12;    // L under the diaphragm
  double smallest_sigma_m = 0.012;  // the narrowest of K's four Gaussians (then 2x, 4x, 8x)
  // The lungs' scales at the run's two ends of the breath, per model lung {lowest, highest}
  // (compile() sets them from the drive). Given, the narrowest Gaussian is the least of
  // `sigma_ladder_m` whose field is steep nowhere in the body at `margin` times them (below,
  // "The narrowest blur"), and `smallest_sigma_m` is ignored; empty: `smallest_sigma_m` as given.
  std::vector<std::array<double, 2>> scale_range = {};
  std::vector<double> sigma_ladder_m = {0.012, 0.016, 0.024, 0.032, 0.048};
  double margin = 1.5;             // as the deflation's smoothing checks 1.5 times its depth
  double steepest_allowed = 0.75;  // the bound on |grad u| (spectral norm) at `margin` times the scales
  double margin_m = 0.08;          // the field's box around the lungs (below them: `below_m`)
  double below_m = 0.20;
  double taper_m = 0.048;  // the field fades to 0 over this much at the box's faces
  double cell_m = 6e-3;    // the precomputed grid's spacing
  // Rounds of successive correction that bring the body's motion across the pleura to the lung's
  // (above, "At the pleura"); 0: the blur alone, as before #45's 2 mm check.
  int pleura_corrections = 1;
};

class BodyMotion {
 public:
  // The field of one frame (the lungs' scales fixed): u(x) as BodyMotion::displacement gives it,
  // the lungs' grids summed once (the same value up to rounding: the sum is taken in another order).
  class Frame {
   public:
    // u(x): trilinear in x's cell, blended over y and z at the cell's two x-nodes first, then
    // along x (the order a Cursor shares along a row). 0 outside the lattice.
    Eigen::Vector3d displacement(const Eigen::Vector3d& x) const;
    // Lookups along rows of points that share y and z (a voxel grid's rows along i on an
    // axis-aligned grid: #50, 120M lookups per native time point): the y-z cell, its fractions
    // and the two x-nodes' y-z blends are kept from the last call and reused while they hold, so
    // that a point costs one blend along x. The same bits as Frame::displacement at every call,
    // whatever was kept (each kept value is what displacement computes afresh). One per thread.
    class Cursor {
     public:
      Eigen::Vector3d displacement(const Frame& frame, const Eigen::Vector3d& x);

     private:
      std::uint64_t frame_id_ = 0;               // the frame whose values are kept; 0: none
      double y_ = 0.0, z_ = 0.0;                 // the row's y and z (LPS metres)
      bool inside_ = false;                      // y and z within the lattice
      const Eigen::Vector3d* column_ = nullptr;  // node (0, by, bz)
      double ty_ = 0.0, tz_ = 0.0;
      std::size_t bx_ = kNoCell;  // the x-cell whose two y-z blends are kept
      Eigen::Vector3d left_, right_;
      static constexpr std::size_t kNoCell = ~std::size_t{0};
    };
    // The pull-back at x outside the lungs: the v with v = -u(x + v) (x + v is the body point the
    // forward field carries to x), to 1e-9 m, started from `guess` (from the row's previous
    // voxels, or -u(x)). The fixed-point iteration v <- -u(x + v) for up to 12 steps (one lookup
    // each), then Newton's method on the trilinear field (its exact gradient in the cell; a
    // fixed-point step where det(I + du/dx) <= 0.1): the iteration is a contraction only where
    // |du/dx| < 1, and below the diaphragm it is not everywhere (#50). 0 where u is 0.
    Eigen::Vector3d inverse(const Eigen::Vector3d& x, const Eigen::Vector3d& guess) const;
    // The pull-back field over the box [lo, hi] (LPS) as a field of its own: inverse() solved at
    // the nodes of a lattice `refine` times finer than u's (u's nodes among them; clipped to the
    // box, one node beyond it, and to u's lattice), trilinear between them, 0 beyond them. A voxel
    // grid asks it at tens of millions of points: one lookup each instead of an iteration (#50).
    // v is as smooth as u (u's 6 mm cells, carried by v), so its trilinear interpolant on a lattice
    // of u's cell / `refine` is within a fraction of a millimetre of the exact inverse
    // (docs/voxels.md gives the figures); at u = 0 (a time point at rest) it is exactly 0.
    Frame inverse_field(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::size_t refine) const;

   private:
    friend class BodyMotion;
    // The y-z blend at one x-node: `p` the node (x, by, bz), ty and tz the fractions.
    Eigen::Vector3d column_blend(const Eigen::Vector3d* p, double ty, double tz) const;
    std::uint64_t id_ = 0;  // unique per frame made (a Cursor's key); 0 for an empty one
    Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
    double h_ = 1.0;
    double inverse_h_ = 1.0;  // 1 / h_: a product per lookup instead of a division
    std::array<std::size_t, 3> size_{0, 0, 0};
    std::vector<Eigen::Vector3d> u_;  // per node, i fastest; empty: nothing moves
  };

  BodyMotion() = default;  // no lungs: nothing moves
  // The unit fields of every lung of `model` (its rest surface, normals, unit displacement and
  // body axes).
  BodyMotion(const Model& model, const BodyMotionOptions& options = {});

  // The displacement (metres, LPS) of body tissue at `x` (outside the lungs) for the lungs'
  // scales (one per model lung); 0 outside the field's box.
  Eigen::Vector3d displacement(const Eigen::Vector3d& x, std::span<const double> scales) const;
  // The field at these scales, for many points.
  Frame frame(std::span<const double> scales) const;
  // The options, `smallest_sigma_m` the narrowest blur used (the ladder's choice, where it chose).
  const BodyMotionOptions& options() const { return options_; }
  // The largest |grad u| (spectral norm) in the body beyond one cell from the pleura, on the
  // grid's nodes, at `margin` times the scale range's ends; 0 where no range was given.
  double steepest() const { return steepest_; }

  // The field as bytes (native byte order; a keyed cache file's payload, body_motion_cached) and
  // back, bit for bit, for the `options` it was made with. from_bytes throws ValueError where the
  // bytes are not a field of this layout.
  std::string to_bytes() const;
  static BodyMotion from_bytes(std::string_view bytes, const BodyMotionOptions& options);

 private:
  BodyMotionOptions options_;
  double steepest_ = 0.0;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();  // the grid's first node (LPS, axis-aligned)
  std::array<std::size_t, 3> size_{0, 0, 0};
  std::vector<std::vector<Eigen::Vector3d>> unit_;  // per lung: u at s = 1 per node, i fastest
};

// A digest (64 hex digits) of everything BodyMotion(model, options) reads: every lung's rest
// surface, normals, region weights and unit displacement in order, the body axes and the options.
std::string body_motion_key(const Model& model, const BodyMotionOptions& options);

// BodyMotion(model, options) read from `lookup` where a run kept it for the same inputs
// (body_motion_key), else computed; kept at `save_to` either way (empty: not kept). #50: two
// convolutions of four Gaussians on a 6 mm lattice and the steepest-gradient check, 0.5 CPU-s for
// two CT lungs, which a run into the same folder would repeat. A damaged file is never used.
// Throws IoError where `save_to` cannot be written or `lookup` exists but cannot be read.
std::shared_ptr<const BodyMotion> body_motion_cached(const Model& model, const BodyMotionOptions& options,
                                                     const std::filesystem::path& lookup,
                                                     const std::filesystem::path& save_to);

}  // namespace pneuma::model
