/* threads.h -- the few thread primitives the library needs (the pool's workers and
 * sleep, the plugin's registry lock): pthreads on POSIX, Win32 on Windows.
 *
 * Windows builds used to take pthreads from mingw-w64's winpthreads, which MSVC does
 * not have and which a DLL then had to carry (statically or as libwinpthread-1.dll).
 * The Win32 primitives below exist in every Windows since Vista (kernel32 and the C
 * runtime's _beginthreadex), so the library needs nothing beyond Windows' own DLLs
 * with any compiler. C11 <threads.h> is no substitute: glibc has it only since 2.28
 * and MSVC only since VS 2022 17.8.
 *
 * Mutexes and condition variables may be defined statically (RBC_MUTEX_INIT); an
 * SRWLOCK and a CONDITION_VARIABLE need no destruction, a pthread one does. */
#ifndef RBC_CORE_THREADS_H
#define RBC_CORE_THREADS_H

#if defined(_WIN32)
#ifndef WIN32_LEAN_AND_MEAN
#define WIN32_LEAN_AND_MEAN
#endif
#ifndef NOMINMAX
#define NOMINMAX
#endif
#include <process.h>
#include <stdint.h>
#include <windows.h>
#else
#include <pthread.h>
#endif

typedef void (*rbc_thread_fn)(void *arg);

/* A thread runs fn(arg). The struct holds fn and arg for the trampoline, so it must
 * stay where it is from rbc_thread_create to rbc_thread_join. */
typedef struct rbc_thread {
#if defined(_WIN32)
    HANDLE h;
#else
    pthread_t h;
#endif
    rbc_thread_fn fn;
    void *arg;
} rbc_thread;

#if defined(_WIN32)
/* _beginthreadex, not CreateThread: a thread that calls the C runtime (the error
 * messages' vsnprintf) gets its runtime state set up and freed with it. */
static inline unsigned __stdcall rbc_thread_tramp(void *p) {
    rbc_thread *t = (rbc_thread *)p;
    t->fn(t->arg);
    return 0;
}
/* 0, or -1 if the thread could not be started. */
static inline int rbc_thread_create(rbc_thread *t, rbc_thread_fn fn, void *arg) {
    t->fn = fn;
    t->arg = arg;
    uintptr_t h = _beginthreadex(NULL, 0, rbc_thread_tramp, t, 0, NULL);
    t->h = (HANDLE)h;
    return h ? 0 : -1;
}
static inline void rbc_thread_join(rbc_thread *t) {
    WaitForSingleObject(t->h, INFINITE);
    CloseHandle(t->h);
}

typedef SRWLOCK rbc_mutex;
#define RBC_MUTEX_INIT SRWLOCK_INIT
static inline void rbc_mutex_init(rbc_mutex *m) { InitializeSRWLock(m); }
static inline void rbc_mutex_destroy(rbc_mutex *m) { (void)m; }
static inline void rbc_mutex_lock(rbc_mutex *m) { AcquireSRWLockExclusive(m); }
static inline void rbc_mutex_unlock(rbc_mutex *m) { ReleaseSRWLockExclusive(m); }

typedef CONDITION_VARIABLE rbc_cond;
static inline void rbc_cond_init(rbc_cond *c) { InitializeConditionVariable(c); }
static inline void rbc_cond_destroy(rbc_cond *c) { (void)c; }
/* May wake spuriously (as pthread_cond_wait): callers wait in a loop. */
static inline void rbc_cond_wait(rbc_cond *c, rbc_mutex *m) {
    SleepConditionVariableSRW(c, m, INFINITE, 0);
}
static inline void rbc_cond_broadcast(rbc_cond *c) { WakeAllConditionVariable(c); }
#else
static inline void *rbc_thread_tramp(void *p) {
    rbc_thread *t = (rbc_thread *)p;
    t->fn(t->arg);
    return NULL;
}
static inline int rbc_thread_create(rbc_thread *t, rbc_thread_fn fn, void *arg) {
    t->fn = fn;
    t->arg = arg;
    return pthread_create(&t->h, NULL, rbc_thread_tramp, t) == 0 ? 0 : -1;
}
static inline void rbc_thread_join(rbc_thread *t) { pthread_join(t->h, NULL); }

typedef pthread_mutex_t rbc_mutex;
#define RBC_MUTEX_INIT PTHREAD_MUTEX_INITIALIZER
static inline void rbc_mutex_init(rbc_mutex *m) { pthread_mutex_init(m, NULL); }
static inline void rbc_mutex_destroy(rbc_mutex *m) { pthread_mutex_destroy(m); }
static inline void rbc_mutex_lock(rbc_mutex *m) { pthread_mutex_lock(m); }
static inline void rbc_mutex_unlock(rbc_mutex *m) { pthread_mutex_unlock(m); }

typedef pthread_cond_t rbc_cond;
static inline void rbc_cond_init(rbc_cond *c) { pthread_cond_init(c, NULL); }
static inline void rbc_cond_destroy(rbc_cond *c) { pthread_cond_destroy(c); }
static inline void rbc_cond_wait(rbc_cond *c, rbc_mutex *m) { pthread_cond_wait(c, m); }
static inline void rbc_cond_broadcast(rbc_cond *c) { pthread_cond_broadcast(c); }
#endif
#endif
