#pragma once

// Runs a command the way the bad-input rostests need: with a time limit, stdout and stderr captured.

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace clod_haptics_test {

/** \brief Exit code (-1: killed by a signal or not started; 124: timed out) and merged output. */
struct Outcome {
  int exitCode = -1;
  std::string output;
};

/** \brief Runs command under `timeout -k 5 limit` (seconds), so a hang shows as 124 or 137. */
inline Outcome run(const std::string& command, const std::string& limit = "30") {
  Outcome o;
  FILE* pipe = popen(("timeout -k 5 " + limit + " " + command + " 2>&1").c_str(), "r");
  if (!pipe) return o;
  std::array<char, 512> buffer;
  while (fgets(buffer.data(), buffer.size(), pipe)) o.output += buffer.data();
  const int status = pclose(pipe);
  o.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return o;
}

}  // namespace clod_haptics_test
