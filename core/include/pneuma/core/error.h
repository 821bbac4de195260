#pragma once
// Error conventions shared by every module.
//
// Libraries report failures by throwing pneuma::Error (never exit()). Its message is already
// the one line a user sees: "<file>:<line>:<col>: <key path>: <what was expected>". The CLI
// prints what() on stderr and exits with code().
#include <stdexcept>
#include <string>

namespace pneuma {

// Process exit codes, documented in README.md.
enum class ExitCode : int {
  ok = 0,
  failure = 1,      // an internal failure (a bug, or a solver that did not converge)
  usage = 2,        // a bad command-line option
  bad_input = 3,    // a bad input file: YAML, mesh, HDF5
  io = 4,           // cannot read or write a file (missing, permissions, disk full)
  unsupported = 5,  // valid input that pneuma cannot handle (e.g. no OpenGL context)
};

// `message` with each NUL byte written as \x00: what() is a C string, and a NUL copied from the
// input would end the message there (the CLI quotes every other unprintable byte the same way).
std::string without_nul(const std::string& message);

class Error : public std::runtime_error {
 public:
  Error(ExitCode code, const std::string& message) : std::runtime_error(without_nul(message)), code_(code) {}
  ExitCode code() const noexcept { return code_; }

 private:
  ExitCode code_;
};

// A bad input file or value: "<where>: <message>".
class InputError : public Error {
 public:
  explicit InputError(const std::string& message) : Error(ExitCode::bad_input, message) {}
};

// A file that cannot be read or written.
class IoError : public Error {
 public:
  explicit IoError(const std::string& message) : Error(ExitCode::io, message) {}
};

// A bad command-line option.
class UsageError : public Error {
 public:
  explicit UsageError(const std::string& message) : Error(ExitCode::usage, message) {}
};

// Something valid that cannot be done here (e.g. a target beyond what the field can reach).
class UnsupportedError : public Error {
 public:
  explicit UnsupportedError(const std::string& message) : Error(ExitCode::unsupported, message) {}
};

// A value outside what a library function accepts (a rate of zero, a clique of 9 hops). The
// message says what was expected; callers that know the file and key path catch it and rethrow
// an InputError that names them. Uncaught, it is still a bad input (exit 3).
class ValueError : public Error {
 public:
  explicit ValueError(const std::string& message) : Error(ExitCode::bad_input, message) {}
};

// "file:line:col" with 1-based line and column (pass 0-based values).
std::string location(const std::string& file, int line0, int column0);

// Debug-only safety check with a message; release builds do not pay for it.
[[noreturn]] void assertion_failed(const char* expr, const char* file, int line, const char* message);
}  // namespace pneuma

#ifdef NDEBUG
#define PNEUMA_ASSERT(expr, message) ((void)0)
#else
#define PNEUMA_ASSERT(expr, message) ((expr) ? (void)0 : ::pneuma::assertion_failed(#expr, __FILE__, __LINE__, message))
#endif
