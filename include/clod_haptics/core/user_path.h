#pragma once

// Header-only so that both the ROS layer (mesh parameters) and the device layer (bag parameters)
// use it without linking each other.

#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

namespace clod_haptics {

/** \brief One place where a path given by a user was looked for. */
struct PathCandidate {
  std::string path;    ///< the absolute path tried (or the path as given when it is absolute)
  std::string origin;  ///< why it was tried, e.g. "relative to the launch directory $PWD"
};

/** \brief The result of resolveUserPath: the file found, and everywhere it was looked for. */
struct UserPathResolution {
  std::string path;                  ///< the first candidate that exists (not a directory); empty if none
  std::vector<PathCandidate> tried;  ///< every candidate, in the order they were tried

  /** \brief Whether a candidate exists. */
  bool found() const { return !path.empty(); }

  /** \brief "A (origin) and B (origin)", for an error message that names every path tried. */
  std::string triedText() const {
    std::string text;
    for (std::size_t k = 0; k < tried.size(); ++k) {
      if (k > 0) text += k + 1 == tried.size() ? " and " : ", ";
      text += tried[k].path + " (" + tried[k].origin + ")";
    }
    return text.empty() ? "nothing (empty path)" : text;
  }
};

/**
 * \brief The directories a relative path is resolved against. Taken from the process by
 * fromEnvironment(); tests fill them in.
 */
struct UserPathBase {
  /**
   * \brief Where the user started roslaunch (or the node): $PWD, which a node inherits from the
   * user's shell while roslaunch runs it in $ROS_HOME. Empty or relative: not used.
   */
  std::string launchDir;
  std::string workingDir;  ///< the process's working directory (ROS_HOME under roslaunch)
  std::string home;        ///< $HOME, for a leading "~/" (the shell does not expand `mesh:=~/x`)

  /** \brief $PWD, the current directory and $HOME of this process. */
  static UserPathBase fromEnvironment() {
    UserPathBase base;
    if (const char* pwd = std::getenv("PWD")) base.launchDir = pwd;
    std::error_code ec;
    const std::filesystem::path cwd = std::filesystem::current_path(ec);
    if (!ec) base.workingDir = cwd.string();
    if (const char* home = std::getenv("HOME")) base.home = home;
    return base;
  }
};

namespace user_path_detail {

/** The path the kernel would open, written without "." / ".." and symlinks where they exist. */
inline std::string tidy(const std::filesystem::path& path) {
  std::error_code ec;
  const std::filesystem::path canonical = std::filesystem::weakly_canonical(path, ec);
  return ec ? path.string() : canonical.string();
}

inline bool isFile(const std::string& path) {
  std::error_code ec;
  return std::filesystem::exists(path, ec) && !std::filesystem::is_directory(path, ec);
}

}  // namespace user_path_detail

/**
 * \brief Finds a file named by a user in a parameter (a mesh, a bag), as the user typed it:
 * - an absolute path is taken as it is (one candidate);
 * - "~" or "~/..." is relative to $HOME (roslaunch's `name:=~/x` reaches the node unexpanded);
 * - a relative path is looked for first relative to the directory roslaunch was started from
 *   (base.launchDir, $PWD), then relative to the process's working directory (base.workingDir,
 *   $ROS_HOME for a node started by roslaunch); the same directory is tried once.
 * The first candidate that exists (and is not a directory) is the result, made absolute; when none
 * does, `path` is empty and `tried` lists every candidate for the error message. Never throws.
 */
inline UserPathResolution resolveUserPath(const std::string& path, const UserPathBase& base) {
  namespace fs = std::filesystem;
  UserPathResolution result;
  if (path.empty()) return result;
  const auto add = [&result](const std::string& candidate, const std::string& origin) {
    for (const PathCandidate& c : result.tried) {
      if (c.path == candidate) return;
    }
    result.tried.push_back({candidate, origin});
  };
  const fs::path given(path);
  if (given.is_absolute()) {
    add(path, "an absolute path");
  } else if ((path == "~" || path.rfind("~/", 0) == 0) && fs::path(base.home).is_absolute()) {
    add(user_path_detail::tidy(fs::path(base.home) / path.substr(path.size() > 1 ? 2 : 1)), "~ is $HOME");
  } else {
    const bool haveLaunchDir = fs::path(base.launchDir).is_absolute();
    const bool haveWorkingDir = fs::path(base.workingDir).is_absolute();
    const std::string fromLaunch = haveLaunchDir ? user_path_detail::tidy(fs::path(base.launchDir) / given) : "";
    const std::string fromWorking = haveWorkingDir ? user_path_detail::tidy(fs::path(base.workingDir) / given) : "";
    if (haveLaunchDir) {
      add(fromLaunch, fromLaunch == fromWorking
                          ? "relative to the launch directory $PWD, also the node's working directory"
                          : "relative to the launch directory $PWD");
    }
    if (haveWorkingDir) {
      add(fromWorking, haveLaunchDir ? "the node's working directory"
                                     : "the node's working directory; $PWD, the launch directory, is not set");
    }
    if (result.tried.empty()) add(path, "as given; neither $PWD nor the working directory is known");
  }
  for (const PathCandidate& c : result.tried) {
    if (user_path_detail::isFile(c.path)) {
      result.path = c.path;
      break;
    }
  }
  return result;
}

/** \brief resolveUserPath against this process's $PWD, working directory and $HOME. */
inline UserPathResolution resolveUserPath(const std::string& path) {
  return resolveUserPath(path, UserPathBase::fromEnvironment());
}

}  // namespace clod_haptics
