#include "clod_tool_io.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>

#include "clod_haptics/core/atomic_file.h"
#include "clod_haptics/core/errors.h"

namespace clod_tool {

using clod_haptics::Vec3;

std::string exitCodeTable() {
  static const std::pair<ExitCode, const char*> kMeanings[] = {
      {kOk, "success"},
      {kInputError, "input error: the mesh or the probe file is missing, unreadable or malformed"},
      {kUsageError, "usage error: unknown command or option, missing value, number outside its bound"},
      {kOutputError, "output error: --out or standard output cannot be written (a regular --out is left as it was)"},
      {kInternalError, "internal error: out of memory or a bug"},
  };
  std::string table = "exit codes:\n";
  for (const auto& m : kMeanings) table += "  " + std::to_string(m.first) + "  " + m.second + "\n";
  return table;
}

// ---- numbers ----

namespace {

std::string shortest(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", v);
  return text;
}

// The text between leading and trailing blanks.
std::string trimmed(const std::string& text) {
  const std::size_t first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(" \t") - first + 1);
}

// Whether text (without surrounding blanks) is one number, as strtod reads it; ERANGE is not an error
// here: an underflow gives the nearest double (subnormal or zero), an overflow +-HUGE_VAL, which the
// bound then refuses.
bool toNumber(const std::string& text, double& value) {
  const std::string t = trimmed(text);
  if (t.empty()) return false;
  char* end = nullptr;
  value = std::strtod(t.c_str(), &end);
  return end == t.c_str() + t.size();
}

}  // namespace

double parseBounded(const std::string& key, const std::string& text, const Bound& bound) {
  double v = 0.0;
  if (!toNumber(text, v)) throw ToolError(kUsageError, key + " expects a number, got '" + text + "'");
  const bool inside = v >= bound.min && v <= bound.max;  // false for NaN
  if (!inside || (bound.integer && v != std::floor(v))) {
    throw ToolError(kUsageError, key + " must be " + (bound.integer ? "an integer" : "a number") + " in [" +
                                     shortest(bound.min) + ", " + shortest(bound.max) + "], got '" + text + "'");
  }
  return v;
}

// ---- the command line ----

Args::Args(int argc, char** argv, const std::vector<std::string>& flags, const std::vector<std::string>& switches) {
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (std::find(switches.begin(), switches.end(), a) != switches.end()) {
      values_[a] = "1";
    } else if (std::find(flags.begin(), flags.end(), a) != flags.end()) {
      if (i + 1 >= argc) throw ToolError(kUsageError, a + " needs a value");
      values_[a] = argv[++i];
    } else {
      throw ToolError(kUsageError, "unknown argument '" + a + "'");
    }
  }
}

std::string Args::get(const std::string& key) const {
  const auto it = values_.find(key);
  if (it == values_.end()) throw ToolError(kUsageError, "missing " + key);
  return it->second;
}

std::string Args::get(const std::string& key, const std::string& fallback) const {
  return has(key) ? get(key) : fallback;
}

double Args::number(const std::string& key, const Bound& bound) const { return parseBounded(key, get(key), bound); }

double Args::number(const std::string& key, const Bound& bound, double fallback) const {
  return has(key) ? number(key, bound) : fallback;
}

// ---- the probe reader ----

namespace {

// Lines of a file, each at most kMaxLineBytes, with a read error told apart from the end of the file.
class LineReader {
 public:
  explicit LineReader(const std::string& path) : path_(path), file_(std::fopen(path.c_str(), "rb")) {
    if (!file_) throw ToolError(kInputError, "cannot open probe file '" + path + "': " + std::strerror(errno));
  }
  ~LineReader() { std::fclose(file_); }
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  // The next line without its "\n" or "\r\n"; false at the end of the file.
  bool next(std::string& line) {
    line.clear();
    int c = 0;
    while ((c = std::getc(file_)) != EOF && c != '\n') {
      if (line.size() == kMaxLineBytes)
        fail("line longer than " + std::to_string(kMaxLineBytes) + " bytes", lineNo_ + 1);
      line.push_back(static_cast<char>(c));
    }
    if (c == EOF && std::ferror(file_)) {
      throw ToolError(kInputError, "reading probe file '" + path_ + "' failed: " + std::strerror(errno));
    }
    if (c == EOF && line.empty()) return false;
    ++lineNo_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  [[noreturn]] void fail(const std::string& problem, std::size_t lineNo) const {
    throw ToolError(kInputError, path_ + ":" + std::to_string(lineNo) + ": " + problem);
  }
  std::size_t lineNo() const { return lineNo_; }

 private:
  std::string path_;
  std::FILE* file_;
  std::size_t lineNo_ = 0;
};

std::vector<std::string> cells(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) out.push_back(cell);
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

// A probe coordinate: a finite number within +-kMaxLength (so differences with mesh points and their
// squares stay finite).
double coordinate(const LineReader& reader, const std::string& cell) {
  double v = 0.0;
  if (!toNumber(cell, v)) reader.fail("expected 'x,y,z', '" + trimmed(cell) + "' is not a number", reader.lineNo());
  if (!(std::fabs(v) <= kMaxLength)) {
    reader.fail("coordinate '" + trimmed(cell) + "' is not a finite number in [-" + shortest(kMaxLength) + ", " +
                    shortest(kMaxLength) + "]",
                reader.lineNo());
  }
  return v;
}

}  // namespace

std::vector<Vec3> readProbes(const std::string& path) {
  LineReader reader(path);
  std::vector<Vec3> probes;
  std::string line;
  bool first = true;
  while (reader.next(line)) {
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    const std::vector<std::string> row = cells(line);
    if (row.size() != 3) reader.fail("expected 3 columns 'x,y,z', got " + std::to_string(row.size()), reader.lineNo());
    double ignored = 0.0;
    const bool header =
        first && std::none_of(row.begin(), row.end(), [&](const std::string& c) { return toNumber(c, ignored); });
    first = false;
    if (header) continue;
    Vec3 p;
    for (int k = 0; k < 3; ++k) p[k] = coordinate(reader, row[k]);  // in order: the first bad cell is named
    probes.push_back(p);
  }
  return probes;
}

// ---- outputs ----

namespace {

std::string parentOf(const std::string& path) {
  const std::string parent = std::filesystem::path(path).parent_path().string();
  return parent.empty() ? "." : parent;
}

// Writes into an open stream, closes it and checks: a full disk shows at the last write or the close.
void writeAndClose(std::ofstream& out, const std::string& path, const std::function<void(std::ostream&)>& write) {
  if (!out) throw clod_haptics::FormatError("cannot open '" + path + "' for writing: " + std::strerror(errno));
  write(out);
  out.close();
  if (!out) throw clod_haptics::FormatError("writing '" + path + "' failed: " + std::strerror(errno));
}

}  // namespace

void checkWritable(const std::string& key, const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) throw ToolError(kOutputError, key + " '" + path + "' is a directory");
    if (::access(path.c_str(), W_OK) != 0) {
      throw ToolError(kOutputError, key + " '" + path + "' is not writable: " + std::strerror(errno));
    }
    if (!S_ISREG(st.st_mode)) return;  // a device or pipe, written in place
  }
  const std::string dir = parentOf(path);
  if (::stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    throw ToolError(kOutputError, key + " '" + path + "': directory '" + dir + "' does not exist");
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw ToolError(kOutputError, key + " '" + path + "': directory '" + dir + "' is not writable");
  }
}

void writeOutput(const std::string& key, const std::string& path, const std::function<void(std::ostream&)>& write) {
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode)) {
    std::ofstream out(path);
    try {
      writeAndClose(out, path, write);
    } catch (const clod_haptics::FormatError& e) {
      throw ToolError(kOutputError, key + ": " + e.what());
    }
    return;
  }
  std::string problem;
  clod_haptics::storeAtomically(
      parentOf(path), path,
      [&](const std::string& tmp) {
        std::ofstream out(tmp);
        writeAndClose(out, tmp, write);
      },
      problem);
  if (!problem.empty()) throw ToolError(kOutputError, key + " '" + path + "' " + problem);
}

void finishStdout() {
  if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
    throw ToolError(kOutputError, std::string("writing standard output failed: ") + std::strerror(errno));
  }
}

}  // namespace clod_tool
