#pragma once

// Runs a command with stdout and stderr captured: with a time limit (run: the bad-input rostests) or without
// (capture: the generator script test).

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "test_timing.h"

namespace clod_haptics_test {

/** \brief Exit code (-1: killed by a signal or not started; 124: timed out) and merged output. */
struct Outcome {
  int exitCode = -1;
  std::string output;
};

/** \brief Runs command through the shell, without a time limit, capturing stdout and stderr. */
inline Outcome capture(const std::string& command) {
  Outcome o;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return o;
  std::array<char, 512> buffer;
  while (fgets(buffer.data(), buffer.size(), pipe)) o.output += buffer.data();
  const int status = pclose(pipe);
  o.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return o;
}

/**
 * \brief Runs command under `timeout -k 5 [-s signal] limit`, so a hang shows as 124 or 137.
 *
 * limit is in seconds of the normal build, scaled by CLOD_TIME_SCALE (slower sanitizer builds); signal (e.g.
 * "INT") is what timeout sends at the limit, its default TERM when empty.
 */
inline Outcome run(const std::string& command, double limit = 30.0, const std::string& signal = "") {
  const std::string timeout =
      "timeout -k 5 " + (signal.empty() ? std::string() : "-s " + signal + " ") + std::to_string(scaled(limit));
  return capture(timeout + " " + command);
}

/**
 * \brief Prefix for `rosrun` that runs Debian's uninstrumented nodelet binary with the ASan runtime preloaded
 * when this build is sanitized (CLOD_SANITIZER_PRELOAD set), so it can load our sanitized nodelet; else empty.
 */
inline std::string nodeletRosrunPrefix() {
  const char* preload = std::getenv("CLOD_SANITIZER_PRELOAD");
  if (!preload || !*preload) return "";
  return std::string("--prefix 'env LD_PRELOAD=") + preload + "' ";
}

}  // namespace clod_haptics_test
