/*
 * A stand-in for Force Dimension's libdhd.so (the DHD SDK's C interface) for Vesalius' tests.
 *
 * It exports the DHD calls listed in shared/HAPTICS.md with the same C types (device IDs as
 * `char`, metres and newtons), keeps one simulated Novint Falcon in memory (system type 60,
 * name "Falcon", max force 8 N), and records every call, so the Rust bindings' FFI path is
 * exercised without hardware. Written for Vesalius from the interface description; no vendor
 * code. dhdGetButtonMask returns `unsigned int`, as in the vendor's dhdc.h.
 *
 * Behaviour worth knowing when reading the tests:
 * - One device at a time. A call naming the open device's ID, or -1 (the default device), is
 *   served; calls with -1 are counted apart (fake_dhd_default_id_calls) because the bindings
 *   must always pass the ID; any other ID fails with -1 and "invalid device ID".
 * - dhdSetForce clips a force above the max force (when that is not negative) to it and returns
 *   DHD_MOTOR_SATURATED (2); with the timeguard knob it returns DHD_TIMEGUARD (1); after the
 *   injected fault it fails with -1. Applied forces go to a log.
 *
 * Control symbols (prefixed fake_dhd_) are for tests; environment knobs, read when the library
 * is loaded and by fake_dhd_reset, serve tests that run the vesalius binary:
 *   FAKE_DHD_FAIL_OPEN=1            dhdOpen fails (no device found)
 *   FAKE_DHD_FAULT_AFTER_FORCES=N   every dhdSetForce after the N-th fails (USB error)
 *   FAKE_DHD_POSITION_M=x,y,z       the end effector's position in metres
 */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fake_common.h"

#define EXPORT __attribute__((visibility("default")))

#define DHD_TIMEGUARD 1
#define DHD_MOTOR_SATURATED 2
#define FORCE_LOG_MAX 200000

#define CALLS(X)                                                                                   \
    X(dhdOpen)                                                                                     \
    X(dhdClose)                                                                                    \
    X(dhdGetSystemType)                                                                            \
    X(dhdGetSystemName)                                                                            \
    X(dhdEnableForce)                                                                              \
    X(dhdGetPosition)                                                                              \
    X(dhdSetForce)                                                                                 \
    X(dhdSetForceAndTorqueAndGripperForce)                                                         \
    X(dhdGetButtonMask)                                                                            \
    X(dhdSetWatchdog)                                                                              \
    X(dhdGetMaxForce)                                                                              \
    X(dhdSetMaxForce)                                                                              \
    X(dhdErrorGetLastStr)

#define AS_ENUM(name) CALL_##name,
enum { CALLS(AS_ENUM) CALL_COUNT };
#define AS_NAME(name) #name,
static const char *const CALL_NAMES[] = {CALLS(AS_NAME)};

struct state {
    long calls[CALL_COUNT];
    int fail_open;
    int open_id;
    int is_open;
    long fault_after_forces;
    long forces_set;
    int timeguard;
    int system_type;
    char system_name[64];
    double max_force_n;
    int force_enabled;
    int watchdog;
    double position_m[3];
    unsigned int buttons;
    double last_force[3];
    long force_log_len;
    long default_id_calls;
    char last_error[256];
};

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static struct state st;
static double force_log[FORCE_LOG_MAX][3];

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
    st.system_type = 60;
    snprintf(st.system_name, sizeof st.system_name, "Falcon");
    st.max_force_n = 8.0;
    st.force_enabled = -1;
    st.watchdog = -1;
    st.fail_open = env_long("FAKE_DHD_FAIL_OPEN", 0) != 0;
    st.fault_after_forces = env_long("FAKE_DHD_FAULT_AFTER_FORCES", 0);
    snprintf(st.last_error, sizeof st.last_error, "no error (fake libdhd)");
    const char *p = getenv("FAKE_DHD_POSITION_M");
    if (p != NULL) {
        double x, y, z;
        if (sscanf(p, "%lf,%lf,%lf", &x, &y, &z) == 3) {
            st.position_m[0] = x;
            st.position_m[1] = y;
            st.position_m[2] = z;
        }
    }
}

__attribute__((constructor)) static void fake_dhd_load(void) {
    pthread_mutex_lock(&lock);
    load_defaults();
    pthread_mutex_unlock(&lock);
}

/* Counts the call and checks the device ID; returns 0 when it names the open device. Takes
 * `lock`, which the caller releases. */
static int enter(int call, char id) {
    pthread_mutex_lock(&lock);
    st.calls[call]++;
    if (id == -1) {
        st.default_id_calls++;
    }
    if (!st.is_open || (id != -1 && (int)id != st.open_id)) {
        snprintf(st.last_error, sizeof st.last_error,
                 "invalid device ID %d (fake libdhd: open device %d, open %d)", (int)id,
                 st.open_id, st.is_open);
        return -1;
    }
    return 0;
}

EXPORT int dhdOpen(void) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_dhdOpen]++;
    int id;
    if (st.fail_open) {
        snprintf(st.last_error, sizeof st.last_error, "no device found (fake libdhd)");
        id = -1;
    } else if (st.is_open) {
        snprintf(st.last_error, sizeof st.last_error, "device already open (fake libdhd)");
        id = -1;
    } else {
        st.is_open = 1;
        id = st.open_id;
    }
    pthread_mutex_unlock(&lock);
    return id;
}

EXPORT int dhdClose(char id) {
    int r = enter(CALL_dhdClose, id);
    if (r == 0) {
        st.is_open = 0;
    }
    pthread_mutex_unlock(&lock);
    return r;
}

EXPORT int dhdGetSystemType(char id) {
    int r = enter(CALL_dhdGetSystemType, id);
    if (r == 0) {
        r = st.system_type;
    }
    pthread_mutex_unlock(&lock);
    return r;
}

EXPORT const char *dhdGetSystemName(char id) {
    int r = enter(CALL_dhdGetSystemName, id);
    pthread_mutex_unlock(&lock);
    /* st.system_name only changes through fake_dhd_set_system, between sessions. */
    return r == 0 ? st.system_name : NULL;
}

EXPORT int dhdEnableForce(unsigned char val, char id) {
    int r = enter(CALL_dhdEnableForce, id);
    if (r == 0) {
        st.force_enabled = val != 0;
    }
    pthread_mutex_unlock(&lock);
    return r;
}

EXPORT int dhdGetPosition(double *px, double *py, double *pz, char id) {
    int r = enter(CALL_dhdGetPosition, id);
    if (r == 0 && (px == NULL || py == NULL || pz == NULL)) {
        snprintf(st.last_error, sizeof st.last_error, "null argument (fake libdhd)");
        r = -1;
    }
    if (r == 0) {
        *px = st.position_m[0];
        *py = st.position_m[1];
        *pz = st.position_m[2];
    }
    pthread_mutex_unlock(&lock);
    return r;
}

/* Called with `lock` held and the ID checked. */
static int apply_force(double fx, double fy, double fz) {
    st.forces_set++;
    if (st.fault_after_forces > 0 && st.forces_set > st.fault_after_forces) {
        snprintf(st.last_error, sizeof st.last_error,
                 "communication error: USB transfer failed (fake libdhd, fault after %ld forces)",
                 st.fault_after_forces);
        return -1;
    }
    int r = st.timeguard ? DHD_TIMEGUARD : 0;
    double norm = sqrt(fx * fx + fy * fy + fz * fz);
    if (st.max_force_n >= 0.0 && norm > st.max_force_n) {
        double k = st.max_force_n / norm;
        fx *= k;
        fy *= k;
        fz *= k;
        r = DHD_MOTOR_SATURATED;
    }
    st.last_force[0] = fx;
    st.last_force[1] = fy;
    st.last_force[2] = fz;
    if (st.force_log_len < FORCE_LOG_MAX) {
        memcpy(force_log[st.force_log_len], st.last_force, sizeof st.last_force);
        st.force_log_len++;
    }
    return r;
}

EXPORT int dhdSetForce(double fx, double fy, double fz, char id) {
    int r = enter(CALL_dhdSetForce, id);
    if (r == 0) {
        r = apply_force(fx, fy, fz);
    }
    pthread_mutex_unlock(&lock);
    return r;
}

EXPORT int dhdSetForceAndTorqueAndGripperForce(double fx, double fy, double fz, double tx,
                                               double ty, double tz, double fg, char id) {
    (void)tx;
    (void)ty;
    (void)tz;
    (void)fg;
    int r = enter(CALL_dhdSetForceAndTorqueAndGripperForce, id);
    if (r == 0) {
        r = apply_force(fx, fy, fz);
    }
    pthread_mutex_unlock(&lock);
    return r;
}

EXPORT unsigned int dhdGetButtonMask(char id) {
    int r = enter(CALL_dhdGetButtonMask, id);
    unsigned int mask = r == 0 ? st.buttons : 0;
    pthread_mutex_unlock(&lock);
    return mask;
}

EXPORT int dhdSetWatchdog(unsigned char duration_125us, char id) {
    int r = enter(CALL_dhdSetWatchdog, id);
    if (r == 0) {
        st.watchdog = duration_125us;
    }
    pthread_mutex_unlock(&lock);
    return r;
}

EXPORT double dhdGetMaxForce(char id) {
    int r = enter(CALL_dhdGetMaxForce, id);
    double f = r == 0 ? st.max_force_n : -1.0;
    pthread_mutex_unlock(&lock);
    return f;
}

EXPORT int dhdSetMaxForce(double f, char id) {
    int r = enter(CALL_dhdSetMaxForce, id);
    if (r == 0) {
        st.max_force_n = f;
    }
    pthread_mutex_unlock(&lock);
    return r;
}

EXPORT const char *dhdErrorGetLastStr(void) {
    pthread_mutex_lock(&lock);
    st.calls[CALL_dhdErrorGetLastStr]++;
    pthread_mutex_unlock(&lock);
    /* Like the SDK's: valid until the next failing call. */
    return st.last_error;
}

/* ---- Control and query symbols for tests ---------------------------------------------- */

/* Closes the device, forgets every call and setting, and rereads the env knobs. */
EXPORT void fake_dhd_reset(void) {
    pthread_mutex_lock(&lock);
    load_defaults();
    pthread_mutex_unlock(&lock);
}

EXPORT void fake_dhd_set_fail_open(int fail) {
    pthread_mutex_lock(&lock);
    st.fail_open = fail != 0;
    pthread_mutex_unlock(&lock);
}

/* The ID dhdOpen hands out (0 to 3). */
EXPORT void fake_dhd_set_open_id(int id) {
    pthread_mutex_lock(&lock);
    st.open_id = id;
    pthread_mutex_unlock(&lock);
}

/* Every dhdSetForce after the `n`-th fails (0: never). */
EXPORT void fake_dhd_set_fault_after_forces(int n) {
    pthread_mutex_lock(&lock);
    st.fault_after_forces = n;
    pthread_mutex_unlock(&lock);
}

/* Whether dhdSetForce returns DHD_TIMEGUARD. */
EXPORT void fake_dhd_set_timeguard(int on) {
    pthread_mutex_lock(&lock);
    st.timeguard = on != 0;
    pthread_mutex_unlock(&lock);
}

EXPORT void fake_dhd_set_system(int type, const char *name, double max_force_n) {
    pthread_mutex_lock(&lock);
    st.system_type = type;
    snprintf(st.system_name, sizeof st.system_name, "%s", name != NULL ? name : "");
    st.max_force_n = max_force_n;
    pthread_mutex_unlock(&lock);
}

EXPORT void fake_dhd_set_position_m(double x, double y, double z) {
    pthread_mutex_lock(&lock);
    st.position_m[0] = x;
    st.position_m[1] = y;
    st.position_m[2] = z;
    pthread_mutex_unlock(&lock);
}

EXPORT void fake_dhd_set_buttons(unsigned int mask) {
    pthread_mutex_lock(&lock);
    st.buttons = mask;
    pthread_mutex_unlock(&lock);
}

/* The last watchdog value set, in units of 125 us; -1 if none was. */
EXPORT int fake_dhd_watchdog(void) {
    FAKE_LOCKED_READ(lock, int, st.watchdog);
}

EXPORT double fake_dhd_max_force(void) {
    FAKE_LOCKED_READ(lock, double, st.max_force_n);
}

/* 1 or 0 as last set by dhdEnableForce; -1 if it was not called. */
EXPORT int fake_dhd_force_enabled(void) {
    FAKE_LOCKED_READ(lock, int, st.force_enabled);
}

EXPORT int fake_dhd_is_open(void) {
    FAKE_LOCKED_READ(lock, int, st.is_open);
}

EXPORT void fake_dhd_last_force(double *out) {
    pthread_mutex_lock(&lock);
    memcpy(out, st.last_force, sizeof st.last_force);
    pthread_mutex_unlock(&lock);
}

/* Copies up to `max` applied forces (3 doubles each) into `out`; returns how many the log holds
 * in all. */
EXPORT long fake_dhd_force_log(double *out, int max) {
    return fake_copy_force_log(&lock, (const double (*)[3])force_log, &st.force_log_len, out, max);
}

/* How often the DHD call `name` was made since the last reset; -1 for a name not exported. */
EXPORT long fake_dhd_call_count(const char *name) {
    return fake_count_calls(&lock, CALL_NAMES, st.calls, CALL_COUNT, name);
}

/* Calls that passed ID -1 (the default device) instead of the ID dhdOpen returned. */
EXPORT long fake_dhd_default_id_calls(void) {
    FAKE_LOCKED_READ(lock, long, st.default_id_calls);
}
