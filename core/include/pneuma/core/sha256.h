// SHA-256 through OpenSSL's EVP interface, for the manifest's file checksums, the DICOM output's
// content-derived UIDs and the voxel files hashed as they are written (one implementation, so all
// hash the same way).
#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>

struct evp_md_ctx_st;  // OpenSSL's EVP_MD_CTX, kept out of this header

namespace pneuma::core {

using Sha256Digest = std::array<unsigned char, 32>;

class Sha256 {
 public:
  Sha256();
  // Appends bytes to the message; returns *this so that parts chain.
  Sha256& update(const void* data, std::size_t size);
  // The digest of everything appended; the object is spent afterwards.
  Sha256Digest finish();

 private:
  struct Free {
    void operator()(evp_md_ctx_st* context) const;
  };
  std::unique_ptr<evp_md_ctx_st, Free> context_;
};

// Lower-case hexadecimal, two digits a byte.
std::string to_hex(const Sha256Digest& digest);

// The digest of a file's bytes, read in 64 KiB chunks. Throws IoError when it cannot be read.
Sha256Digest sha256_of_file(const std::filesystem::path& file);

}  // namespace pneuma::core
