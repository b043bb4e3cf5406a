/*
 * A stand-in for 3D Systems' libHD.so (the OpenHaptics HD API) for Vesalius' tests.
 *
 * It exports the HD calls listed in shared/HAPTICS.md with the same C types, keeps a simulated
 * Phantom Omni in memory (nominal max force 3.3 N, max stiffness 0.7 N/mm), records every call,
 * and runs a real scheduler thread, so the Rust bindings' FFI path (units, the servo callback
 * protocol, error handling) is exercised without hardware. Written for Vesalius from the
 * interface description; no vendor code.
 *
 * Behaviour worth knowing when reading the tests:
 * - Errors go on a per-thread queue (oldest first) that hdGetError pops: a fault raised in
 *   hdEndFrame on the scheduler thread is seen by hdGetError on that thread.
 * - One "tick" is one pass of the scheduler thread over its callbacks; the injected device
 *   fault (HD_DEVICE_FAULT) is raised in the hdEndFrame that ends frame number N.
 * - The fake is strict about the frame protocol: hdBeginFrame inside a frame, hdEndFrame outside
 *   one, and setting HD_CURRENT_FORCE outside a frame queue an error and count as protocol errors.
 * - The current device (hdMakeCurrentDevice, hdBeginFrame) is per thread.
 * - Each device (up to four) has its own stylus position, velocity and buttons and its own last
 *   committed force; the force log holds every frame's force, of whichever device.
 * - Force output starts disabled (the real device starts with it enabled) so a test can see
 *   hdEnable(HD_FORCE_OUTPUT) arrive.
 * - hdScheduleSynchronous runs the callback on the scheduler thread (once per tick until it
 *   returns HD_CALLBACK_DONE) and waits; when the scheduler is not running it calls the callback
 *   once, directly, on the caller's thread.
 *
 * Control symbols (prefixed fake_hd_) are for tests; environment knobs, read when the library is
 * loaded and by fake_hd_reset, serve tests that run the vesalius binary:
 *   FAKE_HD_FAIL_INIT=1|<code>      hdInitDevice fails (1 = HD_COMM_ERROR, or the HD error code)
 *   FAKE_HD_FAIL_START=1            hdStartScheduler fails with HD_TIMER_ERROR
 *   FAKE_HD_FAULT_AFTER_TICKS=N     HD_DEVICE_FAULT is raised at the end of frame N
 *   FAKE_HD_POSITION_MM=x,y,z       every stylus' position in millimetres
 *   FAKE_HD_POSITION_MM_<h>=x,y,z   the position of device h (0-3: the order of hdInitDevice)
 *   FAKE_HD_VELOCITY_MM_S=x,y,z     every stylus' velocity in mm/s (the position stays put)
 */
#define _GNU_SOURCE
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fake_common.h"

typedef unsigned int HHD;
typedef unsigned int HDenum;
typedef unsigned int HDErrorCode;
typedef double HDdouble;
typedef unsigned long HDSchedulerHandle;
typedef unsigned int HDCallbackCode;
typedef HDCallbackCode (*HDSchedulerCallback)(void *);

typedef struct {
    HDErrorCode errorCode;
    int internalErrorCode;
    HHD hHD;
} HDErrorInfo;

#define EXPORT __attribute__((visibility("default")))

#define HD_INVALID_HANDLE 0xFFFFFFFFu
#define HD_CALLBACK_DONE 0u

#define HD_SUCCESS 0x0000u
#define HD_INVALID_ENUM 0x0100u
#define HD_INVALID_VALUE 0x0101u
#define HD_INVALID_OPERATION 0x0102u
#define HD_BAD_HANDLE 0x0104u
#define HD_WARM_MOTORS 0x0200u
#define HD_EXCEEDED_MAX_FORCE 0x0201u
#define HD_EXCEEDED_MAX_FORCE_IMPULSE 0x0202u
#define HD_EXCEEDED_MAX_VELOCITY 0x0203u
#define HD_DEVICE_FAULT 0x0300u
#define HD_COMM_ERROR 0x0302u
#define HD_TIMER_ERROR 0x0304u
#define HD_ILLEGAL_BEGIN 0x0400u
#define HD_ILLEGAL_END 0x0401u
#define HD_SCHEDULER_FULL 0x0501u
#define HD_INVALID_LICENSE 0x0600u

#define HD_CURRENT_BUTTONS 0x2000u
#define HD_CURRENT_POSITION 0x2050u
#define HD_CURRENT_VELOCITY 0x2051u
#define HD_CURRENT_TRANSFORM 0x2052u
#define HD_NOMINAL_MAX_STIFFNESS 0x2602u
#define HD_NOMINAL_MAX_FORCE 0x2603u
#define HD_NOMINAL_MAX_CONTINUOUS_FORCE 0x2604u
#define HD_NOMINAL_MAX_DAMPING 0x2609u
#define HD_CURRENT_FORCE 0x2700u
#define HD_FORCE_OUTPUT 0x4000u
#define HD_CAPABILITY_COUNT 4u

#define MAX_DEVICES 4
#define MAX_CALLBACKS 32
#define ERROR_QUEUE_MAX 32
#define FORCE_LOG_MAX 200000

#define CALLS(X)                                                                                   \
    X(hdInitDevice)                                                                                \
    X(hdDisableDevice)                                                                             \
    X(hdMakeCurrentDevice)                                                                         \
    X(hdGetError)                                                                                  \
    X(hdGetErrorString)                                                                            \
    X(hdEnable)                                                                                    \
    X(hdDisable)                                                                                   \
    X(hdGetDoublev)                                                                                \
    X(hdGetIntegerv)                                                                               \
    X(hdSetDoublev)                                                                                \
    X(hdBeginFrame)                                                                                \
    X(hdEndFrame)                                                                                  \
    X(hdScheduleAsynchronous)                                                                      \
    X(hdScheduleSynchronous)                                                                       \
    X(hdUnschedule)                                                                                \
    X(hdStartScheduler)                                                                            \
    X(hdStopScheduler)                                                                             \
    X(hdSetSchedulerRate)

#define AS_ENUM(name) CALL_##name,
enum { CALLS(AS_ENUM) CALL_COUNT };
#define AS_NAME(name) #name,
static const char *const CALL_NAMES[] = {CALLS(AS_NAME)};

struct callback {
    HDSchedulerCallback fn;
    void *data;
    unsigned short priority;
    int active;
};

struct state {
    long calls[CALL_COUNT];
    unsigned int fail_init_code;
    int fail_start;
    long fault_after_frames;
    int fault_raised;
    double position_mm[MAX_DEVICES][3];
    double velocity_mm_s[MAX_DEVICES][3];
    int buttons[MAX_DEVICES];
    double device_force[MAX_DEVICES][3];
    int device_open[MAX_DEVICES];
    int init_name_given;
    char init_name[128];
    unsigned long rate_hz;
    int capabilities[HD_CAPABILITY_COUNT];
    int in_frame;
    long frames_ended;
    double frame_force[3];
    double last_force[3];
    long force_log_len;
    long protocol_errors;
    struct callback callbacks[MAX_CALLBACKS];
    int scheduler_running;
    int stop_requested;
    pthread_t thread;
    long ticks;
    HDSchedulerCallback sync_fn;
    void *sync_data;
    int sync_pending;
};

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
/* Held by the scheduler thread while it runs callbacks, so hdUnschedule from another thread
 * returns only when the callback is not running and will not run again. */
static pthread_mutex_t dispatch = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t sync_cond = PTHREAD_COND_INITIALIZER;
static struct state st;
static double force_log[FORCE_LOG_MAX][3];

/* Like HD's: the current device is the calling thread's (the scheduler thread makes each
 * callback's device current in turn while owners call from theirs). */
static __thread HHD current = HD_INVALID_HANDLE;
static __thread HDErrorInfo error_queue[ERROR_QUEUE_MAX];
static __thread int error_len;

static void count(int call) {
    pthread_mutex_lock(&lock);
    st.calls[call]++;
    pthread_mutex_unlock(&lock);
}

static void push_error(HDErrorCode code, int internal, HHD hhd) {
    if (error_len < ERROR_QUEUE_MAX) {
        HDErrorInfo e = {code, internal, hhd};
        error_queue[error_len++] = e;
    }
}

/* Called with `lock` held. */
static void protocol_error(HDErrorCode code) {
    st.protocol_errors++;
    push_error(code, 0, current);
}

static long env_long(const char *name, long fallback) {
    const char *v = getenv(name);
    if (v == NULL || *v == '\0') {
        return fallback;
    }
    return strtol(v, NULL, 0);
}

/* Called with `lock` held. */
static void load_defaults(void) {
    memset(&st, 0, sizeof st);
    st.rate_hz = 1000;
    long fail = env_long("FAKE_HD_FAIL_INIT", 0);
    st.fail_init_code = fail == 1 ? HD_COMM_ERROR : (unsigned int)fail;
    st.fail_start = env_long("FAKE_HD_FAIL_START", 0) != 0;
    st.fault_after_frames = env_long("FAKE_HD_FAULT_AFTER_TICKS", 0);
    for (int h = 0; h < MAX_DEVICES; h++) {
        char name[32];
        snprintf(name, sizeof name, "FAKE_HD_POSITION_MM_%d", h);
        const char *p = getenv(name);
        if (p == NULL) {
            p = getenv("FAKE_HD_POSITION_MM");
        }
        double x, y, z;
        if (p != NULL && sscanf(p, "%lf,%lf,%lf", &x, &y, &z) == 3) {
            st.position_mm[h][0] = x;
            st.position_mm[h][1] = y;
            st.position_mm[h][2] = z;
        }
        const char *v = getenv("FAKE_HD_VELOCITY_MM_S");
        if (v != NULL && sscanf(v, "%lf,%lf,%lf", &x, &y, &z) == 3) {
            st.velocity_mm_s[h][0] = x;
            st.velocity_mm_s[h][1] = y;
            st.velocity_mm_s[h][2] = z;
        }
    }
}

/* The device calls address: the current one, or device 0 when none is. Called with `lock`
 * held. */
static HHD addressed(void) {
    return current < MAX_DEVICES ? current : 0;
}

__attribute__((constructor)) static void fake_hd_load(void) {
    pthread_mutex_lock(&lock);
    load_defaults();
    pthread_mutex_unlock(&lock);
}

/* Called with `lock` held. */
static int device_valid(HHD hhd) {
    return hhd < MAX_DEVICES && st.device_open[hhd];
}

EXPORT HHD hdInitDevice(const char *name) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdInitDevice]++;
    st.init_name_given = name != NULL;
    snprintf(st.init_name, sizeof st.init_name, "%s", name != NULL ? name : "");
    if (st.fail_init_code != 0) {
        push_error(st.fail_init_code, -17, HD_INVALID_HANDLE);
        pthread_mutex_unlock(&lock);
        return HD_INVALID_HANDLE;
    }
    for (HHD h = 0; h < MAX_DEVICES; h++) {
        if (!st.device_open[h]) {
            st.device_open[h] = 1;
            current = h;
            pthread_mutex_unlock(&lock);
            return h;
        }
    }
    push_error(HD_COMM_ERROR, -1, HD_INVALID_HANDLE);
    pthread_mutex_unlock(&lock);
    return HD_INVALID_HANDLE;
}

EXPORT void hdDisableDevice(HHD hhd) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdDisableDevice]++;
    if (device_valid(hhd)) {
        st.device_open[hhd] = 0;
    } else {
        push_error(HD_BAD_HANDLE, 0, hhd);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void hdMakeCurrentDevice(HHD hhd) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdMakeCurrentDevice]++;
    if (device_valid(hhd)) {
        current = hhd;
    } else {
        push_error(HD_BAD_HANDLE, 0, hhd);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT HDErrorInfo hdGetError(void) {
    count(CALL_hdGetError);
    HDErrorInfo none = {HD_SUCCESS, 0, HD_INVALID_HANDLE};
    if (error_len == 0) {
        return none;
    }
    HDErrorInfo first = error_queue[0];
    memmove(&error_queue[0], &error_queue[1], (size_t)(error_len - 1) * sizeof first);
    error_len--;
    return first;
}

EXPORT const char *hdGetErrorString(HDErrorCode code) {
    count(CALL_hdGetErrorString);
    switch (code) {
    case HD_SUCCESS: return "no error (fake libHD)";
    case HD_INVALID_ENUM: return "invalid enum (fake libHD)";
    case HD_INVALID_VALUE: return "invalid value (fake libHD)";
    case HD_INVALID_OPERATION: return "invalid operation (fake libHD)";
    case HD_BAD_HANDLE: return "bad device handle (fake libHD)";
    case HD_WARM_MOTORS: return "motors are warm (fake libHD)";
    case HD_EXCEEDED_MAX_FORCE: return "exceeded the maximum force (fake libHD)";
    case HD_EXCEEDED_MAX_FORCE_IMPULSE: return "exceeded the maximum force impulse (fake libHD)";
    case HD_EXCEEDED_MAX_VELOCITY: return "exceeded the maximum velocity (fake libHD)";
    case HD_DEVICE_FAULT: return "device fault: amplifiers off (fake libHD)";
    case HD_COMM_ERROR: return "communication error: no device on the port (fake libHD)";
    case HD_TIMER_ERROR: return "scheduler timer error (fake libHD)";
    case HD_ILLEGAL_BEGIN: return "hdBeginFrame inside a frame (fake libHD)";
    case HD_ILLEGAL_END: return "hdEndFrame outside a frame (fake libHD)";
    case HD_SCHEDULER_FULL: return "scheduler full (fake libHD)";
    case HD_INVALID_LICENSE: return "invalid license (fake libHD)";
    default: return "unknown error (fake libHD)";
    }
}

static void set_capability(int call, HDenum cap, int on) {
    pthread_mutex_lock(&lock);
    st.calls[call]++;
    if (cap >= HD_FORCE_OUTPUT && cap < HD_FORCE_OUTPUT + HD_CAPABILITY_COUNT) {
        st.capabilities[cap - HD_FORCE_OUTPUT] = on;
    } else {
        push_error(HD_INVALID_ENUM, 0, current);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void hdEnable(HDenum cap) { set_capability(CALL_hdEnable, cap, 1); }
EXPORT void hdDisable(HDenum cap) { set_capability(CALL_hdDisable, cap, 0); }

EXPORT void hdGetDoublev(HDenum pname, HDdouble *out) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdGetDoublev]++;
    if (out == NULL) {
        push_error(HD_INVALID_VALUE, 0, current);
    } else if (pname == HD_CURRENT_POSITION) {
        memcpy(out, st.position_mm[addressed()], 3 * sizeof *out);
    } else if (pname == HD_CURRENT_VELOCITY) {
        memcpy(out, st.velocity_mm_s[addressed()], 3 * sizeof *out);
    } else if (pname == HD_CURRENT_TRANSFORM) {
        memset(out, 0, 16 * sizeof *out);
        out[0] = out[5] = out[10] = out[15] = 1.0;
        out[12] = st.position_mm[addressed()][0];
        out[13] = st.position_mm[addressed()][1];
        out[14] = st.position_mm[addressed()][2];
    } else if (pname == HD_CURRENT_FORCE) {
        memcpy(out, st.in_frame ? st.frame_force : st.device_force[addressed()],
               3 * sizeof *out);
    } else if (pname == HD_NOMINAL_MAX_FORCE) {
        out[0] = 3.3;
    } else if (pname == HD_NOMINAL_MAX_CONTINUOUS_FORCE) {
        out[0] = 0.88;
    } else if (pname == HD_NOMINAL_MAX_STIFFNESS) {
        out[0] = 0.7;
    } else if (pname == HD_NOMINAL_MAX_DAMPING) {
        out[0] = 0.002;
    } else {
        push_error(HD_INVALID_ENUM, 0, current);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void hdGetIntegerv(HDenum pname, int *out) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdGetIntegerv]++;
    if (out == NULL) {
        push_error(HD_INVALID_VALUE, 0, current);
    } else if (pname == HD_CURRENT_BUTTONS) {
        out[0] = st.buttons[addressed()];
    } else {
        push_error(HD_INVALID_ENUM, 0, current);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void hdSetDoublev(HDenum pname, const HDdouble *value) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdSetDoublev]++;
    if (value == NULL) {
        push_error(HD_INVALID_VALUE, 0, current);
    } else if (pname != HD_CURRENT_FORCE) {
        push_error(HD_INVALID_ENUM, 0, current);
    } else if (!st.in_frame) {
        protocol_error(HD_INVALID_OPERATION);
    } else {
        memcpy(st.frame_force, value, sizeof st.frame_force);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void hdBeginFrame(HHD hhd) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdBeginFrame]++;
    if (!device_valid(hhd)) {
        push_error(HD_BAD_HANDLE, 0, hhd);
    } else if (st.in_frame) {
        protocol_error(HD_ILLEGAL_BEGIN);
    } else {
        st.in_frame = 1;
        current = hhd;
        /* Like the device: a frame that sets no force commands none. */
        memset(st.frame_force, 0, sizeof st.frame_force);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void hdEndFrame(HHD hhd) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdEndFrame]++;
    if (!device_valid(hhd)) {
        push_error(HD_BAD_HANDLE, 0, hhd);
    } else if (!st.in_frame) {
        protocol_error(HD_ILLEGAL_END);
    } else {
        st.in_frame = 0;
        st.frames_ended++;
        memcpy(st.last_force, st.frame_force, sizeof st.last_force);
        memcpy(st.device_force[hhd], st.frame_force, sizeof st.frame_force);
        if (st.force_log_len < FORCE_LOG_MAX) {
            memcpy(force_log[st.force_log_len], st.frame_force, sizeof st.frame_force);
            st.force_log_len++;
        }
        if (st.fault_after_frames > 0 && !st.fault_raised &&
            st.frames_ended >= st.fault_after_frames) {
            st.fault_raised = 1;
            push_error(HD_DEVICE_FAULT, 42, hhd);
        }
    }
    pthread_mutex_unlock(&lock);
}

EXPORT HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback fn, void *data,
                                                unsigned short priority) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdScheduleAsynchronous]++;
    if (fn == NULL) {
        push_error(HD_INVALID_VALUE, 0, current);
        pthread_mutex_unlock(&lock);
        return 0;
    }
    for (int i = 0; i < MAX_CALLBACKS; i++) {
        if (!st.callbacks[i].active) {
            struct callback c = {fn, data, priority, 1};
            st.callbacks[i] = c;
            pthread_mutex_unlock(&lock);
            return (HDSchedulerHandle)(i + 1);
        }
    }
    push_error(HD_SCHEDULER_FULL, 0, current);
    pthread_mutex_unlock(&lock);
    return 0;
}

static int on_scheduler_thread(void) {
    return st.scheduler_running && pthread_equal(pthread_self(), st.thread);
}

EXPORT void hdUnschedule(HDSchedulerHandle handle) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdUnschedule]++;
    int from_scheduler = on_scheduler_thread();
    pthread_mutex_unlock(&lock);
    if (!from_scheduler) {
        pthread_mutex_lock(&dispatch);
    }
    pthread_mutex_lock(&lock);
    if (handle == 0 || handle > MAX_CALLBACKS || !st.callbacks[handle - 1].active) {
        push_error(HD_INVALID_VALUE, 0, current);
    } else {
        st.callbacks[handle - 1].active = 0;
    }
    pthread_mutex_unlock(&lock);
    if (!from_scheduler) {
        pthread_mutex_unlock(&dispatch);
    }
}

/* Runs the pending synchronous callback, if any; called by the scheduler thread. */
static void run_synchronous(void) {
    pthread_mutex_lock(&lock);
    HDSchedulerCallback fn = st.sync_pending ? st.sync_fn : NULL;
    void *data = st.sync_data;
    pthread_mutex_unlock(&lock);
    if (fn != NULL && fn(data) == HD_CALLBACK_DONE) {
        pthread_mutex_lock(&lock);
        st.sync_pending = 0;
        pthread_cond_broadcast(&sync_cond);
        pthread_mutex_unlock(&lock);
    }
}

static void *scheduler_main(void *unused) {
    (void)unused;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (;;) {
        pthread_mutex_lock(&lock);
        if (st.stop_requested) {
            /* A synchronous call still waiting will not run: release its caller. */
            st.sync_pending = 0;
            pthread_cond_broadcast(&sync_cond);
            pthread_mutex_unlock(&lock);
            break;
        }
        long period_ns = 1000000000L / (long)(st.rate_hz > 0 ? st.rate_hz : 1000);
        int order[MAX_CALLBACKS];
        int n = 0;
        for (int i = 0; i < MAX_CALLBACKS; i++) {
            if (st.callbacks[i].active) {
                int j = n++;
                /* Highest priority first. */
                while (j > 0 &&
                       st.callbacks[order[j - 1]].priority < st.callbacks[i].priority) {
                    order[j] = order[j - 1];
                    j--;
                }
                order[j] = i;
            }
        }
        pthread_mutex_unlock(&lock);

        pthread_mutex_lock(&dispatch);
        run_synchronous();
        for (int k = 0; k < n; k++) {
            pthread_mutex_lock(&lock);
            struct callback c = st.callbacks[order[k]];
            pthread_mutex_unlock(&lock);
            if (!c.active) {
                continue;
            }
            if (c.fn(c.data) == HD_CALLBACK_DONE) {
                pthread_mutex_lock(&lock);
                st.callbacks[order[k]].active = 0;
                pthread_mutex_unlock(&lock);
            }
        }
        pthread_mutex_unlock(&dispatch);

        pthread_mutex_lock(&lock);
        st.ticks++;
        pthread_mutex_unlock(&lock);

        next.tv_nsec += period_ns;
        while (next.tv_nsec >= 1000000000L) {
            next.tv_nsec -= 1000000000L;
            next.tv_sec++;
        }
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL) == EINTR) {
        }
    }
    return NULL;
}

EXPORT void hdScheduleSynchronous(HDSchedulerCallback fn, void *data, unsigned short priority) {
    (void)priority;
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdScheduleSynchronous]++;
    if (fn == NULL) {
        push_error(HD_INVALID_VALUE, 0, current);
        pthread_mutex_unlock(&lock);
        return;
    }
    if (!st.scheduler_running || on_scheduler_thread()) {
        pthread_mutex_unlock(&lock);
        fn(data);
        return;
    }
    while (st.sync_pending && st.scheduler_running) {
        pthread_cond_wait(&sync_cond, &lock);
    }
    if (!st.scheduler_running) {
        pthread_mutex_unlock(&lock);
        return;
    }
    st.sync_fn = fn;
    st.sync_data = data;
    st.sync_pending = 1;
    while (st.sync_pending && st.sync_fn == fn && st.sync_data == data && st.scheduler_running) {
        pthread_cond_wait(&sync_cond, &lock);
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void hdStartScheduler(void) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdStartScheduler]++;
    if (st.fail_start) {
        push_error(HD_TIMER_ERROR, -3, current);
    } else if (!st.scheduler_running) {
        st.stop_requested = 0;
        if (pthread_create(&st.thread, NULL, scheduler_main, NULL) == 0) {
            st.scheduler_running = 1;
        } else {
            push_error(HD_TIMER_ERROR, errno, current);
        }
    }
    pthread_mutex_unlock(&lock);
}

/* Stops the scheduler thread and waits for it (unless called from it). */
static void stop_scheduler(void) {
    pthread_mutex_lock(&lock);
    if (!st.scheduler_running) {
        pthread_mutex_unlock(&lock);
        return;
    }
    st.stop_requested = 1;
    pthread_t thread = st.thread;
    int self = pthread_equal(pthread_self(), thread);
    pthread_mutex_unlock(&lock);
    if (self) {
        pthread_detach(thread);
    } else {
        pthread_join(thread, NULL);
    }
    pthread_mutex_lock(&lock);
    st.scheduler_running = 0;
    st.sync_pending = 0;
    pthread_cond_broadcast(&sync_cond);
    pthread_mutex_unlock(&lock);
}

EXPORT void hdStopScheduler(void) {
    count(CALL_hdStopScheduler);
    stop_scheduler();
}

EXPORT void hdSetSchedulerRate(unsigned long hz) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_hdSetSchedulerRate]++;
    if (hz == 0 || hz > 10000) {
        push_error(HD_INVALID_VALUE, 0, current);
    } else {
        st.rate_hz = hz;
    }
    pthread_mutex_unlock(&lock);
}

/* ---- Control and query symbols for tests ---------------------------------------------- */

/* Stops the scheduler, forgets every call, device and callback, and rereads the env knobs. */
EXPORT void fake_hd_reset(void) {
    stop_scheduler();
    pthread_mutex_lock(&lock);
    load_defaults();
    pthread_mutex_unlock(&lock);
    error_len = 0;
}

/* 0: hdInitDevice succeeds; otherwise the HD error code it fails with. */
EXPORT void fake_hd_set_fail_init(int code) {
    pthread_mutex_lock(&lock);
    st.fail_init_code = (unsigned int)code;
    pthread_mutex_unlock(&lock);
}

EXPORT void fake_hd_set_fail_start(int fail) {
    pthread_mutex_lock(&lock);
    st.fail_start = fail != 0;
    pthread_mutex_unlock(&lock);
}

/* HD_DEVICE_FAULT is raised by the hdEndFrame that ends frame `frames` (0: never). */
EXPORT void fake_hd_set_fault_after_ticks(int frames) {
    pthread_mutex_lock(&lock);
    st.fault_after_frames = frames;
    st.fault_raised = 0;
    pthread_mutex_unlock(&lock);
}

/* Sets every device's stylus position. */
EXPORT void fake_hd_set_position_mm(double x, double y, double z) {
    pthread_mutex_lock(&lock);
    for (int h = 0; h < MAX_DEVICES; h++) {
        st.position_mm[h][0] = x;
        st.position_mm[h][1] = y;
        st.position_mm[h][2] = z;
    }
    pthread_mutex_unlock(&lock);
}

/* Sets one device's stylus position (ignored for a handle out of range). */
EXPORT void fake_hd_set_device_position_mm(unsigned int hhd, double x, double y, double z) {
    pthread_mutex_lock(&lock);
    if (hhd < MAX_DEVICES) {
        st.position_mm[hhd][0] = x;
        st.position_mm[hhd][1] = y;
        st.position_mm[hhd][2] = z;
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void fake_hd_set_velocity_mm_s(double x, double y, double z) {
    pthread_mutex_lock(&lock);
    for (int h = 0; h < MAX_DEVICES; h++) {
        st.velocity_mm_s[h][0] = x;
        st.velocity_mm_s[h][1] = y;
        st.velocity_mm_s[h][2] = z;
    }
    pthread_mutex_unlock(&lock);
}

EXPORT void fake_hd_set_buttons(int buttons) {
    pthread_mutex_lock(&lock);
    for (int h = 0; h < MAX_DEVICES; h++) {
        st.buttons[h] = buttons;
    }
    pthread_mutex_unlock(&lock);
}

/* Passes the scheduler thread made over its callbacks. */
EXPORT long fake_hd_ticks(void) {
    FAKE_LOCKED_READ(lock, long, st.ticks);
}

/* The force (N) committed by the last hdEndFrame, into out[0..3]. */
EXPORT void fake_hd_last_force(double *out) {
    pthread_mutex_lock(&lock);
    memcpy(out, st.last_force, sizeof st.last_force);
    pthread_mutex_unlock(&lock);
}

/* The force (N) the last frame of device `hhd` committed, into out[0..3] (zeros for a handle
 * out of range). */
EXPORT void fake_hd_device_last_force(unsigned int hhd, double *out) {
    pthread_mutex_lock(&lock);
    if (hhd < MAX_DEVICES) {
        memcpy(out, st.device_force[hhd], sizeof st.device_force[hhd]);
    } else {
        memset(out, 0, 3 * sizeof *out);
    }
    pthread_mutex_unlock(&lock);
}

/* Copies up to `max` committed forces (one per frame, 3 doubles each) into `out`; returns how
 * many frames the log holds in all. */
EXPORT long fake_hd_force_log(double *out, int max) {
    return fake_copy_force_log(&lock, (const double (*)[3])force_log, &st.force_log_len, out, max);
}

/* How often the HD call `name` was made since the last reset; -1 for a name not exported. */
EXPORT long fake_hd_call_count(const char *name) {
    return fake_count_calls(&lock, CALL_NAMES, st.calls, CALL_COUNT, name);
}

EXPORT unsigned long fake_hd_scheduler_rate(void) {
    FAKE_LOCKED_READ(lock, unsigned long, st.rate_hz);
}

/* Whether capability `cap` (HD_FORCE_OUTPUT ...) is enabled; -1 for an unknown one. */
EXPORT int fake_hd_is_enabled(unsigned int cap) {
    if (cap < HD_FORCE_OUTPUT || cap >= HD_FORCE_OUTPUT + HD_CAPABILITY_COUNT) {
        return -1;
    }
    pthread_mutex_lock(&lock);
    int on = st.capabilities[cap - HD_FORCE_OUTPUT];
    pthread_mutex_unlock(&lock);
    return on;
}

EXPORT int fake_hd_open_devices(void) {
    pthread_mutex_lock(&lock);
    int n = 0;
    for (int i = 0; i < MAX_DEVICES; i++) {
        n += st.device_open[i];
    }
    pthread_mutex_unlock(&lock);
    return n;
}

EXPORT int fake_hd_active_callbacks(void) {
    pthread_mutex_lock(&lock);
    int n = 0;
    for (int i = 0; i < MAX_CALLBACKS; i++) {
        n += st.callbacks[i].active;
    }
    pthread_mutex_unlock(&lock);
    return n;
}

EXPORT int fake_hd_scheduler_running(void) {
    FAKE_LOCKED_READ(lock, int, st.scheduler_running);
}

/* Frame-protocol misuses seen: begin inside a frame, end outside one, force set outside one. */
EXPORT long fake_hd_protocol_errors(void) {
    FAKE_LOCKED_READ(lock, long, st.protocol_errors);
}

/* Copies the name the last hdInitDevice got into `out`; returns 0 if it got NULL (the default
 * device), 1 otherwise. */
EXPORT int fake_hd_init_name(char *out, int cap) {
    pthread_mutex_lock(&lock);
    if (out != NULL && cap > 0) {
        snprintf(out, (size_t)cap, "%s", st.init_name);
    }
    int given = st.init_name_given;
    pthread_mutex_unlock(&lock);
    return given;
}
