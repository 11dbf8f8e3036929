// The Eigen alignment check (eigen_abi.h): a program compiled with the library's vector flags links; one compiled
// with other flags (AVX against a plain x86-64 library, or the reverse), whose structs holding Eigen members would
// be laid out differently from the library's, fails to link, and the error names the check. Both are compiled and
// linked here, with the compiler and the library this build used.

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include "clod_haptics/core/mesh.h"

namespace {

// Compiles and links a program that includes the core's headers, with extra flags; its output and exit status.
struct Build {
  int status = -1;
  std::string output;
};

Build buildConsumer(const std::string& flags) {
  const std::string dir = ::testing::TempDir();
  const std::string source = dir + "/clod_eigen_abi_consumer.cpp", program = dir + "/clod_eigen_abi_consumer";
  {
    std::ofstream out(source);
    out << "#include \"clod_haptics/core/mesh.h\"\n"
           "int main() { clod_haptics::Vec3 v(1.0, 2.0, 3.0); return v.x() > 0.0 ? 0 : 1; }\n";
  }
  const std::string command = std::string(CLOD_CXX) + " -std=c++17 -O2 " + flags + " -I" + CLOD_INCLUDE_DIR +
                              " -isystem " + CLOD_EIGEN_INCLUDE_DIR + " " + source + " " + CLOD_CORE_LIBRARY + " -o " +
                              program + " 2>&1";
  Build b;
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  if (!pipe) return b;
  std::array<char, 4096> chunk{};
  std::size_t n;
  while ((n = std::fread(chunk.data(), 1, chunk.size(), pipe.get())) > 0) b.output.append(chunk.data(), n);
  b.status = pclose(pipe.release());
  return b;
}

TEST(EigenAbi, AProgramWithTheLibrarysFlagsLinks) {
  const Build b = buildConsumer("");
  EXPECT_EQ(b.status, 0) << b.output;
}

TEST(EigenAbi, AProgramWithOtherVectorFlagsFailsToLinkNamingTheCheck) {
#if defined(__x86_64__)
  // This test is compiled with the library's flags: its alignment is the library's. The other one: AVX's 32 bytes
  // against 16, or back to 16 from a library built with AVX.
  const std::string other = EIGEN_MAX_STATIC_ALIGN_BYTES == 16 ? "-mavx" : "-mno-avx";
  const Build b = buildConsumer(other);
  EXPECT_NE(b.status, 0) << "linked with " << other << ":\n" << b.output;
  EXPECT_NE(b.output.find("sameEigenAlignmentAsTheLibrary"), std::string::npos) << b.output;
#else
  GTEST_SKIP() << "the vector flags tried are x86-64's";
#endif
}

}  // namespace
