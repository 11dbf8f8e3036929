#pragma once
// The OpenHaptics HD headers, made safe to include from C++17. Include it after every other header.
//  - The SDK's hdExport.h defines HDAPI, HDAPIENTRY and HDCALLBACK only `#if defined(linux)`. GCC defines
//    `linux` in its GNU modes but not under strict -std=c++17 (only __linux__), where every declaration
//    would fail: define it when the platform is Linux.
//  - On Linux those macros carry __attribute__((stdcall)), which x86-64 GCC ignores with -Wattributes,
//    and hdDefines.h has MSVC `#pragma deprecated` lines (-Wunknown-pragmas). -Wattributes is silenced for
//    the SDK's headers here (servo callbacks declared HDCALLBACK silence it themselves); GCC before 13
//    cannot silence -Wunknown-pragmas this way, so CMake compiles the backend with -Wno-unknown-pragmas.
//  - hdCompilerConfig.h defines function-like min(a,b) and max(a,b) macros (and TRUE, FALSE, Sleep):
//    min and max are removed again so std::min, std::max and numeric_limits<T>::max() keep working.
#if defined(__linux__) && !defined(linux)
#define linux 1
#endif

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wattributes"
#pragma GCC diagnostic ignored "-Wunknown-pragmas"
#include <HD/hd.h>
#include <HDU/hduError.h>
#pragma GCC diagnostic pop

#undef min
#undef max
