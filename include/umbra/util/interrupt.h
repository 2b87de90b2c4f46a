#pragma once
// SIGINT and SIGTERM stop a render: the handler only records the signal;
// the parser stops between requests, the bucket scheduler between
// buckets, and the frame is then not written (temporaries removed, the
// finished files of earlier frames kept), so `--resume` redoes it.

namespace umbra {

/// Installs the handlers (the command does; a library user may not want
/// them). A second signal kills the process at once, as it would without
/// umbra's handler.
void installInterruptHandlers();
/// The signal that asked to stop, or 0.
int interruptSignal();
inline bool interrupted() { return interruptSignal() != 0; }
/// For tests: as if `signal` had arrived (0 clears it).
void setInterruptForTesting(int signal);

}  // namespace umbra
