/* Fake OpenHaptics header (test/device/fake_libhd): the servo-loop scheduler, declared as the SDK does. */
#ifndef HD_SCHEDULER_H_DEFINE
#define HD_SCHEDULER_H_DEFINE

#include <HD/hdExport.h>
#include <HD/hdCompilerConfig.h>
#include <HD/hdDefines.h>

#ifdef __cplusplus
extern "C" {
#endif

/* What a callback returns: DONE unschedules it, CONTINUE runs it again next tick. */
typedef unsigned int HDCallbackCode;
#define HD_CALLBACK_DONE 0
#define HD_CALLBACK_CONTINUE 1

typedef unsigned long HDSchedulerHandle;
typedef HDCallbackCode(HDCALLBACK* HDSchedulerCallback)(void* pUserData);

typedef unsigned int HDWaitCode;
#define HD_WAIT_CHECK_STATUS 0
#define HD_WAIT_INFINITE 1

HDAPI void HDAPIENTRY hdStartScheduler();
HDAPI void HDAPIENTRY hdStopScheduler();
HDAPI void HDAPIENTRY hdSetSchedulerRate(HDulong nRate);
/* Runs pCallback in the scheduler thread (again while it returns CONTINUE) and waits until it is done. */
HDAPI void HDAPIENTRY hdScheduleSynchronous(HDSchedulerCallback pCallback, void* pUserData, HDushort nPriority);
/* Runs pCallback every tick until it returns DONE or is unscheduled; higher priorities run first. */
HDAPI HDSchedulerHandle HDAPIENTRY hdScheduleAsynchronous(HDSchedulerCallback pCallback, void* pUserData,
                                                          HDushort nPriority);
HDAPI void HDAPIENTRY hdUnschedule(HDSchedulerHandle hHandle);
HDAPI HDboolean HDAPIENTRY hdWaitForCompletion(HDSchedulerHandle hHandle, HDWaitCode param);
/* Seconds since the start of the current scheduler tick (not a clock). */
HDAPI HDdouble HDAPIENTRY hdGetSchedulerTimeStamp();

#ifdef __cplusplus
}
#endif

#endif /* HD_SCHEDULER_H_DEFINE */
