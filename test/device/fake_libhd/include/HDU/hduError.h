/* Fake OpenHaptics utility header (test/device/fake_libhd): error helpers of the SDK's HDU library, which
   the ROS drivers link beside libHD. Plain C declarations without HDAPI, as in the SDK. */
#ifndef hduError_H_
#define hduError_H_

#include <stdio.h>

#include <HD/hd.h>

#ifdef __cplusplus
extern "C" {
#endif

void hduPrintError(FILE* stream, const HDErrorInfo* error, const char* message);
/* A force error (warm motors, exceeded force or velocity): the servo loop may go on. */
HDboolean hduIsForceError(const HDErrorInfo* error);
/* A communication, timer or scheduler error: the servo loop cannot go on. */
HDboolean hduIsSchedulerError(const HDErrorInfo* error);

#ifdef __cplusplus
}
#endif

#endif /* hduError_H_ */
