#pragma once
// Test helper shared by test/device and test/ros: sets $PWD (the directory roslaunch was started from, which
// resolveUserPath reads) for one test and puts the old value back.

#include <cstdlib>
#include <optional>
#include <string>

namespace clod_test {

/** \brief Sets $PWD for its lifetime. */
class ScopedPwd {
 public:
  explicit ScopedPwd(const std::string& value) {
    if (const char* old = std::getenv("PWD")) old_ = old;
    setenv("PWD", value.c_str(), 1);
  }
  ~ScopedPwd() {
    if (old_) {
      setenv("PWD", old_->c_str(), 1);
    } else {
      unsetenv("PWD");
    }
  }
  ScopedPwd(const ScopedPwd&) = delete;
  ScopedPwd& operator=(const ScopedPwd&) = delete;

 private:
  std::optional<std::string> old_;
};

}  // namespace clod_test
