/* Test FMU for the master: the Reference FMU Dahlquist (its sources, shipped in
   tests/data/reference-fmus/Dahlquist.fmu) whose fmi2DoStep answers STEP_STATUS (an
   fmi2Status) from the first step that starts at or after STATUS_AT (s): fmi2Warning
   once (no message logged), fmi2Discard as a partial step (fmi2LastSuccessfulTime half
   way through it, fmi2Terminated TERMINATED) or fmi2Pending (an asynchronous step, which
   fmi2CancelStep cancels), or any other value (an FMU out of the standard: -1, 7). From
   that step on, it may also block BLOCK_S seconds once first (saying "blocking" on
   stderr as it starts: a step that computes for long). fmi2Terminate answers
   TERMINATE_STATUS. Built by tests/status_fmu.py with -DSTEP_STATUS=... -DSTATUS_AT=...
   -DTERMINATED=... -DBLOCK_S=... -DTERMINATE_STATUS=... */

#include <stdio.h>
#include <unistd.h>

#include "fmi2Functions.h" /* first: its macros name the functions, ours rename them */
#undef fmi2DoStep
#undef fmi2GetRealStatus
#undef fmi2GetBooleanStatus
#undef fmi2CancelStep
#undef fmi2Terminate
#define fmi2DoStep reference_fmi2DoStep
#define fmi2GetRealStatus reference_fmi2GetRealStatus
#define fmi2GetBooleanStatus reference_fmi2GetBooleanStatus
#define fmi2CancelStep reference_fmi2CancelStep
#define fmi2Terminate reference_fmi2Terminate
#include "all.c"
#undef fmi2DoStep
#undef fmi2GetRealStatus
#undef fmi2GetBooleanStatus
#undef fmi2CancelStep
#undef fmi2Terminate

static double reached = 0.0; /* s, where the step that did not complete got to */
static int warned = 0;
static int blocked = 0;

/* BLOCK_S seconds asleep, whatever signal the host catches meanwhile (sleep returns
   early on one: the seconds left are slept again) */
static void block(void) {
    fputs("cosim_test_status: blocking\n", stderr);
    fflush(stderr);
    unsigned left = BLOCK_S;
    while (left > 0) {
        left = sleep(left);
    }
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean prior) {
    fmi2Status status = reference_fmi2DoStep(c, t, h, prior);
    if (status != fmi2OK || t + 1e-9 < STATUS_AT) {
        return status;
    }
    reached = t + 0.5 * h;
    if (BLOCK_S > 0 && !blocked++) {
        block();
    }
    if (STEP_STATUS == fmi2Warning && warned++) {
        return fmi2OK;
    }
    return (fmi2Status)STEP_STATUS;
}

FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (s == fmi2LastSuccessfulTime) {
        *value = reached;
        return fmi2OK;
    }
    return reference_fmi2GetRealStatus(c, s, value);
}

FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Boolean *value) {
    if (s == fmi2Terminated) {
        *value = TERMINATED;
        return fmi2OK;
    }
    return reference_fmi2GetBooleanStatus(c, s, value);
}

FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) {
    (void)c;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    fmi2Status status = reference_fmi2Terminate(c);
    return status == fmi2OK ? (fmi2Status)TERMINATE_STATUS : status;
}
