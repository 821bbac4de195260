// NIfTI-1 written from memory (nifti_write.h). The header by ITK 5.2's bundled NIfTI library
// (libITKniftiio, linked through pneuma_itk; a C header, cheap to compile), filled as ITK's
// NiftiImageIO fills it: qform and sform both NIFTI_XFORM_SCANNER_ANAT from the grid in RAS+ mm,
// units mm, scl_slope 1 (tests/voxels/nifti_write_test.cpp: the same bytes but `descrip`).
#include "nifti_write.h"

#include <nifti1_io.h>
#include <tbb/parallel_pipeline.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>
#include <memory>
#include <span>
#include <vector>

#include "direct_file.h"
#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/voxels/gzip.h"

namespace pneuma::voxels {
namespace fs = std::filesystem;
namespace {

constexpr std::size_t kHeaderBytes = 352;  // 348 and the 4 bytes saying "no extensions"

std::size_t value_bytes(NiftiType type) {
  switch (type) {
    case NiftiType::uint8: return 1;
    case NiftiType::int16: return 2;
    case NiftiType::int32:
    case NiftiType::float32: return 4;
  }
  return 0;
}

int datatype(NiftiType type) {
  switch (type) {
    case NiftiType::uint8: return NIFTI_TYPE_UINT8;
    case NiftiType::int16: return NIFTI_TYPE_INT16;
    case NiftiType::int32: return NIFTI_TYPE_INT32;
    case NiftiType::float32: return NIFTI_TYPE_FLOAT32;
  }
  return 0;
}

std::array<std::uint8_t, kHeaderBytes> header(const fs::path& path, const NiftiSpec& spec) {
  const Grid& g = spec.grid;
  for (const std::size_t n : g.size) {
    if (n > 32767) throw ValueError(path.string() + ": a side of more than 32767 voxels; NIfTI-1 holds at most that");
  }
  const bool vector = spec.components > 1;
  std::array<int, 8> dims{vector ? 5 : 3,
                          static_cast<int>(g.size[0]),
                          static_cast<int>(g.size[1]),
                          static_cast<int>(g.size[2]),
                          1,
                          static_cast<int>(spec.components),
                          1,
                          1};
  const std::unique_ptr<nifti_image, void (*)(nifti_image*)> nim(
      nifti_make_new_nim(dims.data(), datatype(spec.type), 0), nifti_image_free);
  if (!nim) throw IoError(path.string() + ": cannot write (the NIfTI library is out of memory)");
  const Eigen::Vector3d spacing_mm = g.spacing_m() * 1e3;
  nim->dx = nim->pixdim[1] = static_cast<float>(spacing_mm.x());
  nim->dy = nim->pixdim[2] = static_cast<float>(spacing_mm.y());
  nim->dz = nim->pixdim[3] = static_cast<float>(spacing_mm.z());
  // NIfTI's world is RAS+: LPS with x and y negated. Computed as ITK's NiftiImageIO computes it,
  // in float, so that every bit is ITK's: the direction made orthonormal by the NIfTI library,
  // the quaternion from it and the origin, the sform that matrix with the spacing on its columns.
  const Eigen::Vector3d spacing_m = g.spacing_m();
  std::array<std::array<float, 3>, 3> axis{};  // axis[a][r]: row r of axis a's unit vector in RAS
  for (int a = 0; a < 3; ++a)
    for (int r = 0; r < 3; ++r)
      axis[static_cast<std::size_t>(a)][static_cast<std::size_t>(r)] =
          static_cast<float>((r < 2 ? -1.0 : 1.0) * (g.ijk_to_lps(r, a) / spacing_m[a]));
  const mat44 rows = nifti_make_orthog_mat44(axis[0][0], axis[0][1], axis[0][2], axis[1][0], axis[1][1], axis[1][2],
                                             axis[2][0], axis[2][1], axis[2][2]);
  mat44 ras{};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) ras.m[r][c] = rows.m[c][r];
    ras.m[r][3] = static_cast<float>((r < 2 ? -1.0 : 1.0) * (g.ijk_to_lps(r, 3) * 1e3));
  }
  ras.m[3][3] = 1.0f;
  nifti_mat44_to_quatern(ras, &nim->quatern_b, &nim->quatern_c, &nim->quatern_d, &nim->qoffset_x, &nim->qoffset_y,
                         &nim->qoffset_z, nullptr, nullptr, nullptr, &nim->qfac);
  nim->qform_code = nim->sform_code = NIFTI_XFORM_SCANNER_ANAT;
  nim->qto_xyz = nim->sto_xyz = ras;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) nim->sto_xyz.m[r][c] *= static_cast<float>(spacing_m[c] * 1e3);
  nim->xyz_units = NIFTI_UNITS_MM;
  nim->scl_slope = 1.0f;
  nim->scl_inter = 0.0f;
  nim->intent_code = spec.intent != 0 ? spec.intent : vector ? NIFTI_INTENT_VECTOR : NIFTI_INTENT_NONE;
  std::strncpy(nim->descrip, spec.description.c_str(), 79);
  nim->nifti_type = NIFTI_FTYPE_NIFTI1_1;
  nim->iname_offset = static_cast<int>(kHeaderBytes);
  nifti_1_header h = nifti_convert_nim2nhdr(nim.get());
  // The unused dimensions as ITK leaves them: size 1, spacing 0.
  for (int d = dims[0] + 1; d < 8; ++d) h.dim[d] = 1;
  for (int d = 4; d < 8; ++d) h.pixdim[d] = 0.0f;
  static_assert(sizeof(nifti_1_header) == 348);
  std::array<std::uint8_t, kHeaderBytes> bytes{};  // the last four zero: no extensions
  std::memcpy(bytes.data(), &h, sizeof h);         // the host's byte order, little-endian (as ITK's writer)
  return bytes;
}

bool gzipped(const fs::path& path) {
  std::string name = path.filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return name.ends_with(".gz");
}

}  // namespace

void write_nifti(const fs::path& path, const NiftiSpec& spec, const NiftiFill& fill) {
  const std::array<std::uint8_t, kHeaderBytes> head = header(path, spec);
  const std::size_t size = value_bytes(spec.type);
  const std::size_t total = kHeaderBytes + spec.grid.voxel_count() * spec.components * size;
  const GzipSettings& gzip = kVoxelGzip;
  const bool compress = gzipped(path);
  // A chunk is one gzip member (cut every member_bytes from the file's start, so a .nii.gz has the
  // bytes it had when ITK wrote the plain file first), or as much of a plain .nii; it ends on a
  // value (kHeaderBytes and the chunk are multiples of 4 bytes).
  const std::size_t chunk_bytes =
      std::min(std::max(gzip.member_bytes > 0 ? gzip.member_bytes : std::size_t{4} << 20, kHeaderBytes), total);
  const std::size_t chunks = (total + chunk_bytes - 1) / chunk_bytes;
  // The chunks flow through fill (in order), compress (in parallel) and write (in order) at once,
  // so the kernel's copy of one chunk into the file overlaps the compression of the next ones
  // (BENCHMARKS.md, "Voxel outputs", #50: the writes were 13 % of a native time point, done
  // while both cores waited). At most kSlots chunks live at a time, each in its own slot: memory
  // bounded by the slots, never by the file, and no fresh pages per chunk.
  constexpr std::size_t kSlots = 8;
  // A slot's raw chunk is block-aligned: a plain .nii's chunks go to the disk from it (DirectFile).
  struct Slot {
    detail::AlignedBytes raw;
    std::vector<std::uint8_t> packed;
    std::size_t size = 0;
  };
  std::array<Slot, kSlots> slots;
  write_atomically(path, [&](const fs::path& tmp) {
    detail::DirectFile out(tmp, path);
    std::size_t next = 0;
    tbb::parallel_pipeline(
        kSlots,
        tbb::make_filter<void, Slot*>(tbb::filter_mode::serial_in_order, [&](tbb::flow_control& control) -> Slot* {
          if (next == chunks) {
            control.stop();
            return nullptr;
          }
          // Live chunks leave in order, so this slot's last one has left.
          Slot& slot = slots[next % kSlots];
          const std::size_t at = next * chunk_bytes;
          slot.size = std::min(chunk_bytes, total - at);
          if (!slot.raw) slot.raw = detail::aligned_bytes(chunk_bytes);
          std::size_t header_part = 0;
          if (at < kHeaderBytes) {
            header_part = kHeaderBytes - at;
            std::memcpy(slot.raw.get(), head.data() + at, header_part);
          }
          if (slot.size > header_part)
            fill((at + header_part - kHeaderBytes) / size, (slot.size - header_part) / size,
                 slot.raw.get() + header_part);
          ++next;
          return &slot;
        }) & tbb::make_filter<Slot*, Slot*>(tbb::filter_mode::parallel, [&](Slot* slot) {
          if (compress) gzip_member(std::span<const std::uint8_t>(slot->raw.get(), slot->size), slot->packed, gzip);
          return slot;
        }) & tbb::make_filter<Slot*, void>(tbb::filter_mode::serial_in_order, [&](Slot* slot) {
          if (compress) {
            out.write(slot->packed.data(), slot->packed.size());
          } else {
            out.write(slot->raw.get(), slot->size);
          }
        }));
    out.close();
  });
}

}  // namespace pneuma::voxels
