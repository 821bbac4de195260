#pragma once
// check_no_fold() (model.h) once for the same surfaces at the same scales (#50: 0.3 CPU-s of CGAL
// for two CT lungs, which a run into the same folder would repeat).
#include <filesystem>
#include <span>
#include <string>

#include "pneuma/model/model.h"

namespace pneuma::model {

// `lookup`: a file a run wrote when its check passed (`save_to`, that run's stage; empty: none),
// holding no_fold_key() of what it checked (docs/formats.md, "self-intersection.check").
struct NoFoldRecord {
  std::filesystem::path lookup;
  std::filesystem::path save_to;
};

// check_no_fold(model, scales), skipped where record.lookup holds this model's and these scales'
// key; the pass is kept at record.save_to either way. A missing, foreign or stale file is no
// error: the surfaces are checked. Returns whether the check was skipped. Throws as
// check_no_fold (nothing is written then), and IoError when record.save_to cannot be written.
bool check_no_fold(const Model& model, std::span<const LungScales> scales, const NoFoldRecord& record);

// A digest (64 hex digits) of what check_no_fold() depends on: every lung's rest surface and
// field in order, each lung's lowest and highest scale, and the check's version.
std::string no_fold_key(const Model& model, std::span<const LungScales> scales);

}  // namespace pneuma::model
