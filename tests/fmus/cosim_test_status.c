/* Test FMU for the master: the Reference FMU Dahlquist (its sources, shipped in
   tests/data/reference-fmus/Dahlquist.fmu) whose fmi2DoStep answers STEP_STATUS (an
   fmi2Status) from the first step that starts at or after STATUS_AT (s): fmi2Warning
   once (no message logged), fmi2Discard as a partial step (fmi2LastSuccessfulTime half
   way through it, fmi2Terminated TERMINATED) or fmi2Pending (an asynchronous step, which
   fmi2CancelStep cancels), or any other value (an FMU out of the standard: -1, 7). From
   that step on, it may also block BLOCK_S seconds once first (saying "blocking" on
   stderr as it starts: a step that computes for long). fmi2Terminate answers
   TERMINATE_STATUS. fmi2EnterInitializationMode, fmi2ExitInitializationMode, fmi2SetReal
   and fmi2SetFMUstate do their work and answer ENTER_STATUS, EXIT_STATUS, SET_REAL_STATUS
   and SET_STATE_STATUS (fmi2OK unless given); fmi2GetFMUstate answers GET_STATE_STATUS,
   taking no state unless that is fmi2OK, and cosim_test_live_states() tells how many
   states taken are not freed yet. Built by tests/status_fmu.py with
   -DSTEP_STATUS=... -DSTATUS_AT=... -DTERMINATED=... -DBLOCK_S=... -DTERMINATE_STATUS=...
   and the others where asked. */

#include <stdio.h>
#include <unistd.h>

#include "fmi2Functions.h" /* first: its macros name the functions, ours rename them */
#undef fmi2DoStep
#undef fmi2GetRealStatus
#undef fmi2GetBooleanStatus
#undef fmi2CancelStep
#undef fmi2Terminate
#undef fmi2EnterInitializationMode
#undef fmi2ExitInitializationMode
#undef fmi2SetReal
#undef fmi2SetFMUstate
#undef fmi2GetFMUstate
#undef fmi2FreeFMUstate
#define fmi2DoStep reference_fmi2DoStep
#define fmi2GetRealStatus reference_fmi2GetRealStatus
#define fmi2GetBooleanStatus reference_fmi2GetBooleanStatus
#define fmi2CancelStep reference_fmi2CancelStep
#define fmi2Terminate reference_fmi2Terminate
#define fmi2EnterInitializationMode reference_fmi2EnterInitializationMode
#define fmi2ExitInitializationMode reference_fmi2ExitInitializationMode
#define fmi2SetReal reference_fmi2SetReal
#define fmi2SetFMUstate reference_fmi2SetFMUstate
#define fmi2GetFMUstate reference_fmi2GetFMUstate
#define fmi2FreeFMUstate reference_fmi2FreeFMUstate
#include "all.c"
#undef fmi2DoStep
#undef fmi2GetRealStatus
#undef fmi2GetBooleanStatus
#undef fmi2CancelStep
#undef fmi2Terminate
#undef fmi2EnterInitializationMode
#undef fmi2ExitInitializationMode
#undef fmi2SetReal
#undef fmi2SetFMUstate
#undef fmi2GetFMUstate
#undef fmi2FreeFMUstate

#ifndef ENTER_STATUS
#define ENTER_STATUS fmi2OK
#endif
#ifndef EXIT_STATUS
#define EXIT_STATUS fmi2OK
#endif
#ifndef SET_REAL_STATUS
#define SET_REAL_STATUS fmi2OK
#endif
#ifndef SET_STATE_STATUS
#define SET_STATE_STATUS fmi2OK
#endif
#ifndef GET_STATE_STATUS
#define GET_STATE_STATUS fmi2OK
#endif

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

/* the reference function's work done; its status, else the one asked for */
static fmi2Status answer(fmi2Status done, int asked) {
    return done == fmi2OK ? (fmi2Status)asked : done;
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    return answer(reference_fmi2EnterInitializationMode(c), ENTER_STATUS);
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return answer(reference_fmi2ExitInitializationMode(c), EXIT_STATUS);
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
    return answer(reference_fmi2SetReal(c, vr, nvr, value), SET_REAL_STATUS);
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    return answer(reference_fmi2SetFMUstate(c, state), SET_STATE_STATUS);
}

static int live_states = 0; /* states taken by fmi2GetFMUstate, not freed yet */

FMI2_Export int cosim_test_live_states(void) {
    return live_states;
}

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    if (GET_STATE_STATUS != fmi2OK) {
        return (fmi2Status)GET_STATE_STATUS;
    }
    fmi2Status status = reference_fmi2GetFMUstate(c, state);
    live_states += status == fmi2OK;
    return status;
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    live_states -= *state != NULL;
    return reference_fmi2FreeFMUstate(c, state);
}
