#include "pneuma/core/atomic_file.h"

#include <unistd.h>

#include <array>
#include <atomic>
#include <cstring>
#include <system_error>

#include "pneuma/core/error.h"

namespace pneuma {
namespace {

// A small fixed table of in-flight temporaries, readable from a signal handler.
constexpr int kMaxPending = 64;
std::array<std::array<char, 4096>, kMaxPending> g_pending{};
std::array<std::atomic<bool>, kMaxPending> g_used{};
std::atomic<unsigned> g_counter{0};

int register_pending(const std::string& path) {
  if (path.size() >= 4096) return -1;
  for (int i = 0; i < kMaxPending; ++i) {
    bool expected = false;
    if (g_used[i].compare_exchange_strong(expected, true)) {
      std::memcpy(g_pending[i].data(), path.c_str(), path.size() + 1);
      return i;
    }
  }
  return -1;
}

void unregister_pending(int slot) {
  if (slot >= 0) g_used[slot].store(false);
}

}  // namespace

PendingFile::PendingFile(std::filesystem::path path) : path_(std::move(path)) {
  namespace fs = std::filesystem;
  const fs::path parent = path_.has_parent_path() ? path_.parent_path() : fs::path(".");
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw IoError(path_.string() + ": cannot create folder '" + parent.string() + "': " + ec.message());
  temporary_ = path_;
  temporary_ += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(g_counter.fetch_add(1));
  slot_ = register_pending(temporary_.string());
}

PendingFile::~PendingFile() {
  if (!committed_) {
    std::error_code ec;
    std::filesystem::remove(temporary_, ec);
  }
  unregister_pending(slot_);
}

void PendingFile::commit() {
  std::error_code ec;
  std::filesystem::rename(temporary_, path_, ec);
  if (ec) throw IoError(path_.string() + ": cannot write file: " + ec.message());
  committed_ = true;
}

void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path&)>& write) {
  PendingFile file(path);
  write(file.temporary());
  file.commit();
}

void write_stream_atomically(const std::filesystem::path& path, bool binary,
                             const std::function<void(std::ostream&)>& write) {
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, binary ? std::ios::binary | std::ios::trunc : std::ios::trunc);
    if (!out) throw IoError(path.string() + ": cannot open for writing: " + std::strerror(errno));
    write(out);
    out.close();
    if (!out) throw IoError(path.string() + ": write failed (disk full?)");
  });
}

void remove_pending_temporaries() noexcept {
  for (int i = 0; i < kMaxPending; ++i) {
    if (g_used[i].load()) ::unlink(g_pending[i].data());
  }
}

}  // namespace pneuma
