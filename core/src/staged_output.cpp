#include "pneuma/core/staged_output.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <optional>
#include <system_error>

#include "pneuma/core/error.h"

namespace pneuma {
namespace fs = std::filesystem;
namespace {

// Stages in flight, readable from a signal handler (as atomic_file.cpp's temporaries).
constexpr int kMaxStages = 8;
std::array<std::array<char, 4096>, kMaxStages> g_stages{};
std::array<std::atomic<bool>, kMaxStages> g_used{};
std::atomic<unsigned> g_counter{0};

int register_stage(const std::string& path) {
  if (path.size() >= 4096) return -1;
  for (int i = 0; i < kMaxStages; ++i) {
    bool expected = false;
    if (g_used[i].compare_exchange_strong(expected, true)) {
      std::memcpy(g_stages[i].data(), path.c_str(), path.size() + 1);
      return i;
    }
  }
  return -1;
}

void unregister_stage(int slot) {
  if (slot >= 0) g_used[slot].store(false);
}

// rm -r with system calls only (openat, getdents64, unlinkat, close): safe in a signal handler.
// Entries removed while the folder is read can shift the listing, so it is read until empty.
void remove_tree_signal_safe(int parent_fd, const char* name, int depth) noexcept {
  const int fd = ::openat(parent_fd, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) {
    ::unlinkat(parent_fd, name, 0);
    return;
  }
  alignas(dirent64) char buffer[4096];
  for (int pass = 0; pass < 16 && depth < 8; ++pass) {
    ::lseek(fd, 0, SEEK_SET);
    bool removed = false;
    for (;;) {
      const ssize_t n = ::getdents64(fd, buffer, sizeof buffer);
      if (n <= 0) break;
      for (ssize_t offset = 0; offset < n;) {
        const auto* entry = reinterpret_cast<const dirent64*>(buffer + offset);
        offset += entry->d_reclen;
        if (std::strcmp(entry->d_name, ".") == 0 || std::strcmp(entry->d_name, "..") == 0) continue;
        if (entry->d_type == DT_DIR) remove_tree_signal_safe(fd, entry->d_name, depth + 1);
        else ::unlinkat(fd, entry->d_name, 0);
        removed = true;
      }
    }
    if (!removed) break;
  }
  ::close(fd);
  ::unlinkat(parent_fd, name, AT_REMOVEDIR);
}

// The pid in "<prefix><pid>-<n>" or "<name>.tmp-<pid>-<n>", if the name has that shape.
std::optional<pid_t> pid_after(const std::string& name, const std::string& marker) {
  const auto at = name.rfind(marker);
  if (at == std::string::npos) return std::nullopt;
  const std::string rest = name.substr(at + marker.size());
  const auto dash = rest.find('-');
  if (dash == 0 || dash == std::string::npos || rest.find_first_not_of("0123456789-") != std::string::npos) {
    return std::nullopt;
  }
  try {
    return static_cast<pid_t>(std::stol(rest.substr(0, dash)));
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

bool process_is_gone(pid_t pid) { return pid != ::getpid() && ::kill(pid, 0) != 0 && errno == ESRCH; }

// A stage whose lock nobody holds belongs to a dead process. Without a lock file (killed
// between creating the folder and its lock) the pid in its name decides.
bool stage_is_dead(const fs::path& stage, pid_t owner) {
  const int fd = ::open((stage / "lock").c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return process_is_gone(owner);
  const bool dead = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
  ::close(fd);  // releases the lock we may have taken
  return dead;
}

void remove_leftovers_of_dead_runs(const fs::path& folder) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.starts_with(kStagePrefix)) {
      const auto owner = pid_after(name, kStagePrefix);
      if (!owner || !entry.is_directory(ec)) continue;
      if (!stage_is_dead(entry.path(), *owner)) {
        throw IoError(folder.string() + ": another pneuma run (process " + std::to_string(*owner) +
                      ") is writing its outputs here; wait for it or choose another output folder");
      }
      fs::remove_all(entry.path(), ec);
    } else if (const auto owner = pid_after(name, ".tmp-"); owner && process_is_gone(*owner)) {
      fs::remove(entry.path(), ec);
    }
  }
}

}  // namespace

StagedOutput::StagedOutput(fs::path folder) : folder_(std::move(folder)) {
  std::error_code ec;
  fs::create_directories(folder_, ec);
  if (ec) throw IoError(folder_.string() + ": cannot create the output folder: " + ec.message());
  remove_leftovers_of_dead_runs(folder_);
  stage_ = fs::absolute(folder_) /
           (kStagePrefix + std::to_string(::getpid()) + "-" + std::to_string(g_counter.fetch_add(1)));
  if (!fs::create_directory(stage_, ec) || ec) {
    throw IoError(stage_.string() + ": cannot create the stage for this run's outputs: " +
                  (ec ? ec.message() : std::string("it exists")));
  }
  slot_ = register_stage(stage_.string());
  lock_fd_ = ::open((stage_ / "lock").c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd_ < 0 || ::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    const std::string why = std::strerror(errno);
    if (lock_fd_ >= 0) ::close(lock_fd_);
    unregister_stage(slot_);
    fs::remove_all(stage_, ec);
    throw IoError(stage_.string() + ": cannot lock the stage: " + why);
  }
}

StagedOutput::~StagedOutput() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(stage_, ec);
  }
  unregister_stage(slot_);
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

void StagedOutput::commit(const std::vector<std::string>& obsolete, const std::string& last) {
  std::error_code ec;
  std::vector<fs::path> entries;
  for (const auto& entry : fs::directory_iterator(stage_, ec)) {
    if (entry.path().filename() != "lock") entries.push_back(entry.path());
  }
  if (ec) throw IoError(stage_.string() + ": cannot list the stage: " + ec.message());
  std::stable_partition(entries.begin(), entries.end(),
                        [&](const fs::path& entry) { return entry.filename() != last; });
  const fs::path replaced = stage_ / "replaced";
  for (const auto& from : entries) {
    const fs::path to = folder_ / from.filename();
    // A file is replaced by rename() at once; a folder (frames/) cannot be renamed over a
    // non-empty one, so the old one is moved into the stage first and removed with it.
    if (fs::is_directory(fs::symlink_status(to, ec)) || (fs::is_directory(from) && fs::exists(to, ec))) {
      fs::create_directories(replaced, ec);
      fs::rename(to, replaced / from.filename(), ec);
      if (ec) throw IoError(to.string() + ": cannot replace the previous output: " + ec.message());
    }
    fs::rename(from, to, ec);
    if (ec) throw IoError(to.string() + ": cannot move the output into place: " + ec.message());
  }
  for (const auto& name : obsolete) {
    const fs::path relative(name);
    if (relative.empty() || relative.is_absolute() || relative.begin()->string() == ".." ||
        std::distance(relative.begin(), relative.end()) != 1) {
      continue;  // only top-level names inside the folder
    }
    fs::remove_all(folder_ / relative, ec);
  }
  committed_ = true;
  unregister_stage(slot_);
  slot_ = -1;
  fs::remove_all(stage_, ec);
}

void remove_pending_stages() noexcept {
  for (int i = 0; i < kMaxStages; ++i) {
    if (g_used[i].load()) remove_tree_signal_safe(AT_FDCWD, g_stages[i].data(), 0);
  }
}

}  // namespace pneuma
