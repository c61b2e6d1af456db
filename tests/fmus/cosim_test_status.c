/* Test FMU for the master: the Reference FMU Dahlquist (its sources, shipped in
   tests/data/reference-fmus/Dahlquist.fmu) whose fmi2DoStep answers STEP_STATUS (an
   fmi2Status) from the first step that starts at or after STATUS_AT (s): fmi2Warning
   once (no message logged), fmi2Discard as a partial step (fmi2LastSuccessfulTime half
   way through it, fmi2Terminated TERMINATED) or fmi2Pending (an asynchronous step, which
   fmi2CancelStep cancels). Built by tests/status_fmu.py with -DSTEP_STATUS=...
   -DSTATUS_AT=... -DTERMINATED=... */

#include "fmi2Functions.h" /* first: its macros name the functions, ours rename them */
#undef fmi2DoStep
#undef fmi2GetRealStatus
#undef fmi2GetBooleanStatus
#undef fmi2CancelStep
#define fmi2DoStep reference_fmi2DoStep
#define fmi2GetRealStatus reference_fmi2GetRealStatus
#define fmi2GetBooleanStatus reference_fmi2GetBooleanStatus
#define fmi2CancelStep reference_fmi2CancelStep
#include "all.c"
#undef fmi2DoStep
#undef fmi2GetRealStatus
#undef fmi2GetBooleanStatus
#undef fmi2CancelStep

static double reached = 0.0; /* s, where the step that did not complete got to */
static int warned = 0;

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean prior) {
    fmi2Status status = reference_fmi2DoStep(c, t, h, prior);
    if (status != fmi2OK || t + 1e-9 < STATUS_AT) {
        return status;
    }
    reached = t + 0.5 * h;
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
