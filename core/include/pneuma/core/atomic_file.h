#pragma once
// Atomic output: write to "<path>.tmp-<pid>-<n>" in the same folder, then rename over <path>.
// A failure or an interruption never leaves a partial file under the final name.
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

namespace pneuma {

// Calls write(tmp_path) and renames tmp_path to path when it returns. If write throws, the
// temporary file is removed and the exception propagates. Creates missing parent folders.
// Throws IoError when the folder cannot be created or the rename fails.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp_path)>& write);

// The common case: a stream. Checks the stream state after write() and after closing it, so
// a full disk is reported rather than silently truncating the file.
void write_stream_atomically(const std::filesystem::path& path, bool binary,
                             const std::function<void(std::ostream&)>& write);

// A file written over time (e.g. across the frames of a run): open it under pending.temporary(),
// call commit() once complete. Destroyed without commit(), it removes the temporary; on
// Ctrl-C remove_pending_temporaries() does. Creates missing parent folders.
class PendingFile {
 public:
  explicit PendingFile(std::filesystem::path path);
  ~PendingFile();
  PendingFile(const PendingFile&) = delete;
  PendingFile& operator=(const PendingFile&) = delete;
  const std::filesystem::path& path() const { return path_; }
  const std::filesystem::path& temporary() const { return temporary_; }
  // Renames the temporary to the final path. Throws IoError when that fails.
  void commit();

 private:
  std::filesystem::path path_;
  std::filesystem::path temporary_;
  int slot_ = -1;
  bool committed_ = false;
};

// Removes every temporary file still registered (called from the CLI's SIGINT handler, so
// Ctrl-C leaves no half-written file behind). Async-signal-safe enough for that use: it only
// calls unlink() on paths prepared in advance.
void remove_pending_temporaries() noexcept;

}  // namespace pneuma
