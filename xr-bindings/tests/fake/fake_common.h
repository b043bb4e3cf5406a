/*
 * What the fake vendor libraries (fake_hd.c, fake_dhd.c) share: their state sits behind one
 * mutex each, and tests read it through small locked getters, a call counter and a force log.
 * Header-only (static functions), so each library keeps its own copy and exports nothing more.
 */
#ifndef VESALIUS_FAKE_COMMON_H
#define VESALIUS_FAKE_COMMON_H

#include <pthread.h>
#include <string.h>

/* The body of a getter: `expr` (of `type`) read under `mutex`. */
#define FAKE_LOCKED_READ(mutex, type, expr)                                                        \
    do {                                                                                           \
        pthread_mutex_lock(&(mutex));                                                              \
        type fake_value_ = (expr);                                                                 \
        pthread_mutex_unlock(&(mutex));                                                            \
        return fake_value_;                                                                        \
    } while (0)

/* Copies up to `max` entries of a force log (3 doubles each, `*len` of them) into `out` under
 * `mutex`; returns how many the log holds in all. */
static inline long fake_copy_force_log(pthread_mutex_t *mutex, const double (*log)[3],
                                       const long *len, double *out, int max) {
    pthread_mutex_lock(mutex);
    long n = *len < max ? *len : max;
    if (out != NULL && n > 0) {
        memcpy(out, log, (size_t)n * sizeof log[0]);
    }
    long total = *len;
    pthread_mutex_unlock(mutex);
    return total;
}

/* How often the call `name` (one of `count` names) was made, read under `mutex`; -1 for a name
 * not among them. */
static inline long fake_count_calls(pthread_mutex_t *mutex, const char *const *names,
                                    const long *calls, int count, const char *name) {
    for (int i = 0; i < count; i++) {
        if (name != NULL && strcmp(name, names[i]) == 0) {
            pthread_mutex_lock(mutex);
            long n = calls[i];
            pthread_mutex_unlock(mutex);
            return n;
        }
    }
    return -1;
}

#endif
