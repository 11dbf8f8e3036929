/* Fake OpenHaptics header (test/device/fake_libhd): the umbrella header, as the SDK's <HD/hd.h>. */
#ifndef HD_H_DEFINE
#define HD_H_DEFINE

#include <HD/hdExport.h>
#include <HD/hdCompilerConfig.h>
#include <HD/hdDefines.h>
#include <HD/hdDevice.h>
#include <HD/hdScheduler.h>

#endif /* HD_H_DEFINE */
