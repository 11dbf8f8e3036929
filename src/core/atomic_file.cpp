#include "clod_haptics/core/atomic_file.h"

#include <unistd.h>

#include <filesystem>
#include <sstream>
#include <thread>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

void storeAtomically(const std::string& directory, const std::string& path,
                     const std::function<void(const std::string& tmp)>& write, std::string& problem) {
  std::ostringstream tmp;
  tmp << path << ".tmp." << ::getpid() << "." << std::this_thread::get_id();
  std::error_code ec;
  try {
    std::filesystem::create_directories(directory, ec);
    write(tmp.str());
    std::filesystem::rename(tmp.str(), path, ec);
    if (ec) throw FormatError("cannot rename '" + tmp.str() + "' to '" + path + "': " + ec.message());
  } catch (const FormatError& e) {
    std::filesystem::remove(tmp.str(), ec);
    if (!problem.empty()) problem += "; ";
    problem += std::string("not stored: ") + e.what();
  }
}

}  // namespace clod_haptics
