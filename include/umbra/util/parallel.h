#pragma once
// umbra's fork-join parallelism: oneTBB's parallel_for, parallel_invoke,
// task_group and task_arena::execute, with the hand-offs spelled out for
// ThreadSanitizer.
//
// Debian's libtbb is not built with ThreadSanitizer, so TSan never sees a
// worker take a task from the thread that forked it, nor that thread's wait
// end after the last task. Without those edges a worker's read of a
// variable on the forking thread's stack (a vector captured by reference,
// say) and the forking thread's later write to the same address, once the
// stack is reused, looked like a race; the worker's stack was often too old
// to restore, so no suppression could match it. Every umbra fork-join goes
// through these functions, which tell TSan what TBB guarantees: all that
// the forking thread did comes before each task, and each task comes
// before the join. In builds without TSan the annotations are empty.

#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/parallel_invoke.h>
#include <oneapi/tbb/task_arena.h>
#include <oneapi/tbb/task_group.h>

#include <utility>

#if defined(__SANITIZE_THREAD__)
#define UMBRA_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define UMBRA_TSAN 1
#endif
#endif

#ifdef UMBRA_TSAN
#include <sanitizer/tsan_interface.h>
#endif

namespace umbra {

/// The happens-before edges of one fork-join: fork() on the forking thread
/// before the tasks start, enter()/leave() around every task, join() on the
/// forking thread after the wait returns.
class ForkJoinEdges {
public:
    void fork() { release(&m_fork); }
    void enter() { acquire(&m_fork); }
    void leave() { release(&m_join); }
    void join() { acquire(&m_join); }

    /// `fn` as one task of this fork-join.
    template <class Fn>
    auto task(Fn&& fn) {
        enter();
        struct Leave {
            ForkJoinEdges* edges;
            ~Leave() { edges->leave(); }
        } leaving{this};
        return fn();
    }

private:
#ifdef UMBRA_TSAN
    static void acquire(void* a) { __tsan_acquire(a); }
    static void release(void* a) { __tsan_release(a); }
#else
    static void acquire(void*) {}
    static void release(void*) {}
#endif
    char m_fork = 0, m_join = 0;
};

/// tbb::parallel_for over [first, last) calling body(i).
template <class Index, class Body, class... Partitioner>
void parallelFor(Index first, Index last, const Body& body, Partitioner&&... partitioner) {
    ForkJoinEdges edges;
    edges.fork();
    tbb::parallel_for(
        first, last, [&](Index i) { edges.task([&] { body(i); }); }, std::forward<Partitioner>(partitioner)...);
    edges.join();
}

/// tbb::parallel_for over a blocked range, calling body(range).
template <class Range, class Body>
void parallelForRange(const Range& range, const Body& body) {
    ForkJoinEdges edges;
    edges.fork();
    tbb::parallel_for(range, [&](const Range& r) { edges.task([&] { body(r); }); });
    edges.join();
}

/// tbb::parallel_invoke of two functions.
template <class F0, class F1>
void parallelInvoke(const F0& f0, const F1& f1) {
    ForkJoinEdges edges;
    edges.fork();
    tbb::parallel_invoke([&] { edges.task(f0); }, [&] { edges.task(f1); });
    edges.join();
}

/// `fn` run in `arena` (on a worker when the calling thread cannot join it).
template <class Fn>
void runInArena(tbb::task_arena& arena, const Fn& fn) {
    ForkJoinEdges edges;
    edges.fork();
    arena.execute([&] { edges.task(fn); });
    edges.join();
}

/// A tbb::task_group whose tasks and wait carry the same edges.
class TaskGroup {
public:
    template <class Fn>
    void run(Fn fn) {
        m_edges.fork();
        m_group.run([this, fn = std::move(fn)] { m_edges.task(fn); });
    }
    void wait() {
        m_group.wait();
        m_edges.join();
    }

private:
    ForkJoinEdges m_edges;
    tbb::task_group m_group;
};

}  // namespace umbra
