#pragma once

// clod_tool's inputs and outputs: the exit codes, the command line with its numeric bounds, the probe
// reader and the output files. No ROS, no detection: what the commands share.

#include <functional>
#include <iosfwd>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_tool {

/** \brief The exit codes of every command; --help prints them from exitCodeTable(). */
enum ExitCode : int {
  kOk = 0,
  kInputError = 1,     ///< the mesh or the probe file is missing, unreadable or malformed
  kUsageError = 2,     ///< the command line: unknown command or option, missing value, number out of its bound
  kOutputError = 3,    ///< --out (or standard output) cannot be created or written
  kInternalError = 4,  ///< anything else: out of memory, a bug
};

/** \brief The table of exit codes, one line per code, for --help. */
std::string exitCodeTable();

/** \brief An error that ends the command: main prints "clod_tool: what()" and exits with code. */
class ToolError : public std::runtime_error {
 public:
  ToolError(ExitCode code, const std::string& what) : std::runtime_error(what), code_(code) {}
  /** \brief The exit code the error ends the program with. */
  ExitCode code() const { return code_; }

 private:
  ExitCode code_;
};

/** \brief The closed range a numeric option accepts, and whether it must be an integer. */
struct Bound {
  double min;
  double max;
  bool integer = false;
};

/**
 * \brief The largest length (coordinate, radius, clustering distance, probe coordinate) the tool
 * accepts. The sphere placement forms fourth powers of lengths (squared norms of cross products of
 * edges); with every length and every difference of coordinates below a few 1e12, those stay below
 * about 1e50, far from DBL_MAX (1.8e308), and squared distances from probes stay exact enough. It is
 * also far below the core's own kMaxRadius (1e150), above which a query answers no contact. In metres
 * 1e12 is seven times the Earth-Sun distance: no model needs more.
 */
constexpr double kMaxLength = 1e12;
/**
 * \brief The smallest largest side of a loaded mesh: fourth powers of lengths of 1e-12 are 1e-48,
 * far above the smallest normal double (2.2e-308), so areas and normals do not underflow to zero.
 */
constexpr double kMinExtent = 1e-12;

/** \brief Splits argv[2..] into options with a value (flags) and switches; unknown ones are a usage error. */
class Args {
 public:
  Args(int argc, char** argv, const std::vector<std::string>& flags, const std::vector<std::string>& switches);
  /** \brief Whether the option was given. */
  bool has(const std::string& key) const { return values_.count(key) > 0; }
  /** \brief The option's text; a usage error when missing. */
  std::string get(const std::string& key) const;
  /** \brief The option's text, or fallback when missing. */
  std::string get(const std::string& key, const std::string& fallback) const;
  /** \brief The option as a number within bound; a usage error when missing, not a number or outside. */
  double number(const std::string& key, const Bound& bound) const;
  /** \brief The same, fallback when missing. */
  double number(const std::string& key, const Bound& bound, double fallback) const;

 private:
  std::map<std::string, std::string> values_;
};

/**
 * \brief text as a number within bound, or a usage error naming key and the bound. Subnormal numbers
 * (1e-320) are numbers; text beyond the double range (1e400) is refused as out of bound.
 */
double parseBounded(const std::string& key, const std::string& text, const Bound& bound);

/**
 * \brief Reads "x,y,z" rows. The first row may be a header when none of its three cells is a number
 * ("x,y,z"); any other row must be three finite numbers within +-kMaxLength. Blank lines are skipped,
 * "\r\n" is accepted. An input error names the file and line for a read error (a directory), a line
 * longer than kMaxLineBytes or a malformed row.
 */
std::vector<clod_haptics::Vec3> readProbes(const std::string& path);

/** \brief The longest probe line read; a longer one (a binary file, /dev/zero) is an input error. */
constexpr std::size_t kMaxLineBytes = 4096;

/**
 * \brief Checks, before any work, that path can be written: an existing directory is refused; an
 * existing file or device must be writable; a new file needs an existing, writable directory.
 * An output error naming key otherwise.
 */
void checkWritable(const std::string& key, const std::string& path);

/**
 * \brief Writes path with write(stream): a regular (or new) file through a temporary file in the same
 * directory, closed, checked, then renamed over path, so a failure leaves neither a partial path nor
 * the temporary file; a device or pipe (/dev/stdout) is written in place. An output error naming key
 * when a write or the close fails.
 */
void writeOutput(const std::string& key, const std::string& path, const std::function<void(std::ostream&)>& write);

/** \brief Flushes standard output; an output error when it failed (a full disk, a closed pipe). */
void finishStdout();

}  // namespace clod_tool
