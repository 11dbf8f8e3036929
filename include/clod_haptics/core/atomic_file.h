#pragma once

#include <functional>
#include <string>

namespace clod_haptics {

/**
 * \brief Stores a cache file so readers see a whole file or none: write(tmp) writes under a name no
 * other writer uses (path plus process and thread id), which is then renamed to path. Creates the
 * directory. A FormatError from write or a failed rename leaves no file behind and is appended to
 * problem ("not stored: ..."); nothing throws, a cache that cannot store still serves.
 */
void storeAtomically(const std::string& directory, const std::string& path,
                     const std::function<void(const std::string& tmp)>& write, std::string& problem);

}  // namespace clod_haptics
