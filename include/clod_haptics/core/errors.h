#pragma once

#include <stdexcept>
#include <string>

namespace clod_haptics {

/** \brief Base of every error the core library throws; catch this to catch them all. */
class ClodError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/**
 * \brief A mesh could not be loaded: missing file, format assimp cannot read, no triangles or
 * non-finite coordinates. The message names the path and the reason.
 */
class MeshLoadError : public ClodError {
 public:
  MeshLoadError(const std::string& path, const std::string& reason)
      : ClodError("cannot load mesh '" + path + "': " + reason), path_(path), reason_(reason) {}
  /** \brief The path that failed. */
  const std::string& path() const { return path_; }
  /** \brief Why it failed, without the path. */
  const std::string& reason() const { return reason_; }

 private:
  std::string path_;
  std::string reason_;
};

/** \brief A parameter is out of its domain (negative or NaN distance or radius, bad scale, ...). */
class InvalidParameter : public ClodError {
 public:
  using ClodError::ClodError;
};

/** \brief A sphere set that does not fit the mesh it is used with (built for another mesh or scale, or corrupt). */
class SphereSetMismatch : public ClodError {
 public:
  using ClodError::ClodError;
};

/** \brief A file written by this package (sphere set, cache) is unreadable or inconsistent. */
class FormatError : public ClodError {
 public:
  using ClodError::ClodError;
};

}  // namespace clod_haptics
