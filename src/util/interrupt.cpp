#include "umbra/util/interrupt.h"

#include <atomic>
#include <csignal>

namespace umbra {

namespace {

std::atomic<int> g_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "set from a signal handler");

extern "C" void onInterrupt(int signal) { g_signal.store(signal, std::memory_order_relaxed); }

}  // namespace

void installInterruptHandlers() {
    struct sigaction sa {};
    sa.sa_handler = onInterrupt;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND;  // the second signal takes the default action
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
}

int interruptSignal() { return g_signal.load(std::memory_order_relaxed); }

void setInterruptForTesting(int signal) { g_signal.store(signal, std::memory_order_relaxed); }

}  // namespace umbra
