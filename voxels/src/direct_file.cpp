// A file written past the page cache (direct_file.h).
#include "direct_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <string>
#include <utility>

#include "pneuma/core/error.h"
#include "pneuma/voxels/written_digest.h"

namespace pneuma::voxels::detail {
namespace {

constexpr std::size_t kHeldBytes = std::size_t{4} << 20;  // the gathering buffer: writes of 4 MiB

std::size_t round_up(std::size_t bytes) { return (bytes + kDirectAlign - 1) / kDirectAlign * kDirectAlign; }

// The files written, by device and inode, with the size and modification time they had when
// closed (anything that rewrites one changes one of them) and their digest.
struct Written {
  std::size_t size = 0;
  std::pair<long long, long long> mtime{};  // seconds, nanoseconds
  std::string sha256;
};
std::mutex written_mutex;
std::map<std::pair<unsigned long long, unsigned long long>, Written>& written_files() {
  static std::map<std::pair<unsigned long long, unsigned long long>, Written> files;
  return files;
}
std::pair<unsigned long long, unsigned long long> file_key(const struct stat& s) {
  return {static_cast<unsigned long long>(s.st_dev), static_cast<unsigned long long>(s.st_ino)};
}
std::pair<long long, long long> file_mtime(const struct stat& s) {
  return {static_cast<long long>(s.st_mtim.tv_sec), static_cast<long long>(s.st_mtim.tv_nsec)};
}

}  // namespace

void AlignedFree::operator()(std::uint8_t* p) const { std::free(p); }

AlignedBytes aligned_bytes(std::size_t bytes) {
  auto* p = static_cast<std::uint8_t*>(std::aligned_alloc(kDirectAlign, std::max(round_up(bytes), kDirectAlign)));
  if (p == nullptr) throw std::bad_alloc();
  return AlignedBytes(p);
}

DirectFile::DirectFile(const std::filesystem::path& path, std::filesystem::path name)
    : name_(std::move(name)), held_(aligned_bytes(kHeldBytes)) {
  constexpr int kFlags = O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC;
  fd_ = ::open(path.c_str(), kFlags | O_DIRECT, 0666);
  if (fd_ < 0 && errno == EINVAL) fd_ = ::open(path.c_str(), kFlags, 0666);  // no O_DIRECT here (tmpfs)
  if (fd_ < 0) throw IoError(name_.string() + ": cannot write (" + std::strerror(errno) + "; is the folder writable?)");
}

DirectFile::~DirectFile() {
  if (fd_ >= 0) ::close(fd_);  // an unwinding write: write_atomically removes the temporary
}

void DirectFile::write_at(const std::uint8_t* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::pwrite(fd_, data, size, static_cast<off_t>(offset_));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno == EINVAL && (::fcntl(fd_, F_GETFL) & O_DIRECT) != 0) {
      // A file system that opened the file direct but will not take this write so: the page cache.
      if (::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) & ~O_DIRECT) == 0) continue;
    }
    if (n <= 0)
      throw IoError(name_.string() + ": cannot write (" + (n < 0 ? std::strerror(errno) : "no space") +
                    "; disk full?)");
    data += n;
    size -= static_cast<std::size_t>(n);
    offset_ += static_cast<std::size_t>(n);
  }
}

void DirectFile::flush_blocks() {
  const std::size_t whole = held_size_ / kDirectAlign * kDirectAlign;
  write_at(held_.get(), whole);
  std::memmove(held_.get(), held_.get() + whole, held_size_ - whole);
  held_size_ -= whole;
}

void DirectFile::write(const std::uint8_t* data, std::size_t size) {
  hash_.update(data, size);
  if (held_size_ == 0 && reinterpret_cast<std::uintptr_t>(data) % kDirectAlign == 0) {
    const std::size_t whole = size / kDirectAlign * kDirectAlign;
    write_at(data, whole);
    data += whole;
    size -= whole;
  }
  while (size > 0) {
    const std::size_t n = std::min(size, kHeldBytes - held_size_);
    std::memcpy(held_.get() + held_size_, data, n);
    held_size_ += n;
    data += n;
    size -= n;
    if (held_size_ == kHeldBytes) flush_blocks();
  }
}

void DirectFile::close() {
  const std::size_t length = offset_ + held_size_;
  if (held_size_ > 0) {
    // The last partial block padded to a whole one (O_DIRECT's unit), then the file cut to its length.
    std::memset(held_.get() + held_size_, 0, round_up(held_size_) - held_size_);
    write_at(held_.get(), round_up(held_size_));
    held_size_ = 0;
  }
  if (::ftruncate(fd_, static_cast<off_t>(length)) != 0)
    throw IoError(name_.string() + ": cannot write (" + std::strerror(errno) + ")");
  std::string hex = core::to_hex(hash_.finish());
  struct stat s {};
  if (::fstat(fd_, &s) == 0) {
    const std::lock_guard lock(written_mutex);
    written_files()[file_key(s)] = {static_cast<std::size_t>(s.st_size), file_mtime(s), std::move(hex)};
  }
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throw IoError(name_.string() + ": cannot write (" + std::strerror(errno) + "; disk full?)");
}

}  // namespace pneuma::voxels::detail

namespace pneuma::voxels {

std::optional<std::string> written_sha256(const std::filesystem::path& path) {
  struct stat s {};
  if (::stat(path.c_str(), &s) != 0) return std::nullopt;
  const std::lock_guard lock(detail::written_mutex);
  const auto it = detail::written_files().find(detail::file_key(s));
  if (it == detail::written_files().end() || it->second.size != static_cast<std::size_t>(s.st_size) ||
      it->second.mtime != detail::file_mtime(s))
    return std::nullopt;
  return it->second.sha256;
}

}  // namespace pneuma::voxels
