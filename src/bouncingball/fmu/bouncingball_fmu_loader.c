/* The BouncingBall FMU's binary: a thin FMI 2.0 layer in front of pythonfmu's binary.
 *
 * It does what pythonfmu's Linux binary does not (see docs/fmu.md):
 *   1. In a master without Python (a plain C or C++ master) it starts a Python before pythonfmu's
 *      binary is loaded: the one the FMU was built with, or else one on PATH with the same
 *      version, numpy and scikit-sundae (find_python). It loads that libpython with RTLD_GLOBAL,
 *      so the Py* symbols of pythonfmu's binary and of every extension module (math, numpy,
 *      scikit-sundae) resolve, and initialises it as that python executable, so that its
 *      sys.path (standard library, site-packages of its virtual environment) is that Python's.
 *      No LD_PRELOAD, PYTHONPATH or PYTHONHOME needed. In a master that runs Python itself
 *      (FMPy, libcosimpy) that Python is used as it is.
 *   2. pythonfmu reports a Python exception as fmi2Fatal and has no way to return fmi2Error.
 *      Here, a slave that logs an error during a call makes the call return fmi2Error; a warning
 *      it logs is only logged (finish() in bouncingball_fmu_python.h: the one rule for both versions).
 *      A fatal status from pythonfmu becomes fmi2Error for this instance only, which is then
 *      refused further calls (pythonfmu has already released its Python objects).
 *   3. pythonfmu 0.7.0 releases its interpreter state twice at process exit; the loader
 *      releases it once, first (see open_inner() in bouncingball_fmu_python.h).
 *   4. pythonfmu does not keep FMI 2.0's co-simulation state machine, and an unknown value
 *      reference raises inside it (fmi2Fatal, the instance is gone). The loader keeps the state
 *      machine (ALLOWED, one row per call) and checks value references against the variable
 *      table (BB_VARIABLE_TYPES): a call not allowed in the current state, or a reference that is
 *      not a variable of that type, gets fmi2Error and a log line, and changes nothing.
 *   5. pythonfmu, in a Python that lacks numpy or scikit-sundae, fails inside fmi2Instantiate with a
 *      fmi2Fatal "[ctor] findClass ... ModuleNotFoundError" that some masters show only at debug level.
 *      Before the first instance is forwarded, the loader runs BB_HOST_CHECK (bouncingball.fmu.host_check)
 *      in the interpreter pythonfmu is about to use: if it lacks them, fmi2Instantiate logs one line
 *      (that Python, what it lacks, the pip install that fixes it) and returns NULL; pythonfmu never runs.
 * Everything else is forwarded unchanged. Built by bouncingball.fmu.build with
 * -DBB_LIBPYTHON="path of libpython", -DBB_PYTHON="path of the python executable" and
 * -DBB_INNER="file name of pythonfmu's binary, next to this one", -DBB_PYTHON_VERSION="3.X" and
 * -DBB_VARIABLE_TYPES="RRI..." (the type of each value reference, from the variable table) and
 * -DBB_HOST_CHECK="Python code" (bouncingball.fmu.host_check.check_source()).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <libgen.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <wchar.h>

#include "fmi2Functions.h"

#ifndef BB_LIBPYTHON
#error "define BB_LIBPYTHON, the path of the libpython to load in a master without Python"
#endif
#ifndef BB_PYTHON
#error "define BB_PYTHON, the path of the python executable whose environment a master without Python gets"
#endif
#ifndef BB_INNER
#error "define BB_INNER, the file name of pythonfmu's binary next to this one"
#endif
#ifndef BB_PYTHON_VERSION
#error "define BB_PYTHON_VERSION, the Python version (3.X) pythonfmu's binary was built for"
#endif
#ifndef BB_VARIABLE_TYPES
#error "define BB_VARIABLE_TYPES, the type (R, I, B or S) of each value reference 0, 1, ... in order"
#endif
#ifndef BB_HOST_CHECK
#error "define BB_HOST_CHECK, the Python code that leaves in `problem` what the host's Python lacks (\"\" if nothing)"
#endif

/* pythonfmu's functions, loaded once per process (bouncingball_fmu_python.h) */
#define FMI_PREFIX fmi2
#define FMI_INSTANCE fmi2Component
#define FMI_STATE_TYPE fmi2FMUstate
#define GET_STATE GetFMUstate
#define SET_STATE SetFMUstate
#define FREE_STATE FreeFMUstate
#define STATE_SIZE SerializedFMUstateSize
#define SERIALIZE_STATE SerializeFMUstate
#define DESERIALIZE_STATE DeSerializeFMUstate
#define INNER_FUNCTIONS(X) \
    X(SetDebugLogging) X(Instantiate) X(FreeInstance) X(SetupExperiment) X(EnterInitializationMode) \
    X(ExitInitializationMode) X(Terminate) X(Reset) X(GetReal) X(GetInteger) X(GetBoolean) X(GetString) \
    X(SetReal) X(SetInteger) X(SetBoolean) X(SetString) X(GetFMUstate) X(SetFMUstate) X(FreeFMUstate) \
    X(SerializedFMUstateSize) X(SerializeFMUstate) X(DeSerializeFMUstate) X(GetDirectionalDerivative) \
    X(SetRealInputDerivatives) X(GetRealOutputDerivatives) X(DoStep) X(CancelStep) X(GetStatus) \
    X(GetRealStatus) X(GetIntegerStatus) X(GetBooleanStatus) X(GetStringStatus)
static const char *const TYPE_NAMES[] = {"Real", "Integer", "Boolean", "String"};

/* FMI 2.0 co-simulation states (FMI 2.0.4, section 4.2.4). A slave that completes its steps
 * synchronously is never "step in progress"; the error state is not entered, because a refused
 * call or bad input changes nothing and the instance stays usable. */
typedef enum { INSTANTIATED, INITIALIZATION_MODE, STEP_COMPLETE, TERMINATED } State;
static const char *const STATE_NAMES[] = {"instantiated", "initialization mode", "step complete", "terminated"};
#define IN(state) (1u << (state))
#define ANY (IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(STEP_COMPLETE) | IN(TERMINATED))
#define INITIALIZED (IN(INITIALIZATION_MODE) | IN(STEP_COMPLETE) | IN(TERMINATED))
#define SETTABLE (IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(STEP_COMPLETE))

/* The states each call is allowed in: the table of FMI 2.0.4 section 4.2.4, without the states
 * this slave never enters. */
#define ALLOWED_SetDebugLogging ANY
#define ALLOWED_SetupExperiment IN(INSTANTIATED)
#define ALLOWED_EnterInitializationMode IN(INSTANTIATED)
#define ALLOWED_ExitInitializationMode IN(INITIALIZATION_MODE)
#define ALLOWED_Terminate IN(STEP_COMPLETE)
#define ALLOWED_Reset ANY
#define ALLOWED_GetReal INITIALIZED
#define ALLOWED_GetInteger INITIALIZED
#define ALLOWED_GetBoolean INITIALIZED
#define ALLOWED_GetString INITIALIZED
#define ALLOWED_SetReal SETTABLE
#define ALLOWED_SetInteger SETTABLE
#define ALLOWED_SetBoolean SETTABLE
#define ALLOWED_SetString SETTABLE
#define ALLOWED_GetFMUstate ANY
#define ALLOWED_SetFMUstate ANY
#define ALLOWED_FreeFMUstate ANY
#define ALLOWED_SerializedFMUstateSize ANY
#define ALLOWED_SerializeFMUstate ANY
#define ALLOWED_DeSerializeFMUstate ANY
#define ALLOWED_GetDirectionalDerivative INITIALIZED
#define ALLOWED_SetRealInputDerivatives SETTABLE
#define ALLOWED_GetRealOutputDerivatives (IN(STEP_COMPLETE) | IN(TERMINATED))
#define ALLOWED_DoStep IN(STEP_COMPLETE)
#define ALLOWED_CancelStep 0u /* only while a step is in progress, which never happens here */
#define ALLOWED_GetStatus (IN(STEP_COMPLETE) | IN(TERMINATED))
#define ALLOWED_GetRealStatus (IN(STEP_COMPLETE) | IN(TERMINATED))
#define ALLOWED_GetIntegerStatus (IN(STEP_COMPLETE) | IN(TERMINATED))
#define ALLOWED_GetBooleanStatus (IN(STEP_COMPLETE) | IN(TERMINATED))
#define ALLOWED_GetStringStatus (IN(STEP_COMPLETE) | IN(TERMINATED))

typedef struct Instance {
    fmi2Component inner;
    fmi2CallbackFunctions master; /* the master's callbacks */
    fmi2CallbackFunctions own;    /* handed to pythonfmu: our logger, the master's memory functions */
    char *name;
    fmi2Boolean logging_on;
    fmi2Status worst;             /* worst status logged during the current call */
    int dead;                     /* pythonfmu returned fmi2Fatal: its instance is gone */
    int ended;                    /* the compiled step raised: its state unknown, no further call taken */
    State state;
    double *served_values;        /* what is served without entering Python (bouncingball_fmu_python.h) */
    intptr_t *served_control;
    struct Instance *next;        /* the list of live instances */
} Instance;

#include "bouncingball_fmu_python.h"

static void tell(Instance *c, fmi2Status status, const char *category, const char *message)
{
    if (c->master.logger != NULL) {
        c->master.logger(c->master.componentEnvironment, c->name, status, category, "%s", message);
    }
}

static int in_mode(const Instance *c, unsigned mask) { return (mask & IN(c->state)) != 0; }

static const char *mode_name(const Instance *c)
{
    (void)c;
    return "FMI 2.0 co-simulation";
}

static int restorable(Instance *c, int state)
{
    if (state >= INSTANTIATED && state <= TERMINATED) {
        return 1;
    }
    say(c, fmi2Error, "fmi2DeSerializeFMUstate: these bytes are not a state of this FMU: nothing was done");
    return 0;
}

/* The logger pythonfmu calls: remember the worst status, pass the message on. pythonfmu always
 * logs here (it is instantiated with logging on); messages with status fmi2OK reach the master
 * only while it has logging on, warnings and errors always. */
static void log_message(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status,
                        fmi2String category, fmi2String message, ...)
{
    Instance *c = (Instance *)environment;
    if (note(c, status) && c->master.logger != NULL) {
        c->master.logger(c->master.componentEnvironment, name, status, category, "%s", message);
    }
}

/* FORWARD for a getter or setter of one type: its value references are checked first. */
#define FORWARD_VALUES(function, type, serve, forward, ...)                                           \
    do {                                                                                              \
        CHECK(function)                                                                               \
        if (nvr > 0 && vr == NULL) {                                                                  \
            say(c_, fmi2Error, "%s: vr is NULL for %zu value references", FMI_STRING(function), nvr); \
            return fmi2Error;                                                                         \
        }                                                                                             \
        if (!of_type(c_, FMI_STRING(function), vr, nvr, type)) {                                      \
            return fmi2Error;                                                                         \
        }                                                                                             \
        serve;                                                                                        \
        forward(function, vr, nvr, ##__VA_ARGS__);                                                    \
    } while (0)

/* A setter forwarded. */
#define SET_CALL(function, ...) CALL_TO(c_->state, function, ##__VA_ARGS__)

/* The getter and setter of one type of variable; the getter serves (SERVE_VALUES) what it can. */
#define VALUES_OF(type, ctype, letter, serve)                                                              \
    fmi2Status fmi2Get##type(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr, ctype value[]) \
    {                                                                                                       \
        FORWARD_VALUES(Get##type, letter, serve, READ_CALL, value);                                         \
    }                                                                                                       \
    fmi2Status fmi2Set##type(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr,            \
                             const ctype value[])                                                           \
    {                                                                                                       \
        FORWARD_VALUES(Set##type, letter, (void)0, SET_CALL, value);                                        \
    }

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    char problem[4096];
    Instance *c;
    if (!can_instantiate(problem, sizeof problem)) {
        if (functions != NULL && functions->logger != NULL) {
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError", "%s",
                              problem);
        }
        return NULL;
    }
    if (functions == NULL) {
        return NULL; /* FMI requires the callbacks; without a logger there is no one to tell */
    }
    c = new_instance(instanceName, loggingOn);
    if (c == NULL) {
        return NULL;
    }
    c->master = *functions;
    c->own = c->master;
    c->own.logger = log_message;
    c->own.componentEnvironment = c;
    if (c->own.allocateMemory == NULL || c->own.freeMemory == NULL) { /* never hand pythonfmu a NULL allocator */
        c->own.allocateMemory = calloc;
        c->own.freeMemory = free;
    }
    MAKING(c, c->inner = inner.Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, &c->own, visible,
                                           fmi2True));
    return keep(c);
}

void fmi2FreeInstance(fmi2Component c) { free_instance(c); }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories;
    (void)categories;
    return set_logging(c, loggingOn);
}

fmi2Status fmi2SetupExperiment(fmi2Component instance, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    FORWARD(SetupExperiment, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component instance) { FORWARD_TO(INITIALIZATION_MODE, EnterInitializationMode); }

fmi2Status fmi2ExitInitializationMode(fmi2Component instance) { FORWARD_TO(STEP_COMPLETE, ExitInitializationMode); }

fmi2Status fmi2Terminate(fmi2Component instance) { FORWARD_TO(TERMINATED, Terminate); }

fmi2Status fmi2Reset(fmi2Component instance) { return reset_instance(instance); }

#define AS_BOOLEAN(x) ((x) != 0.0)
VALUES_OF(Real, fmi2Real, 'R', SERVE_VALUES((fmi2Real), vr, nvr, value))
VALUES_OF(Integer, fmi2Integer, 'I', SERVE_VALUES((fmi2Integer), vr, nvr, value))
VALUES_OF(Boolean, fmi2Boolean, 'B', SERVE_VALUES(AS_BOOLEAN, vr, nvr, value))
VALUES_OF(String, fmi2String, 'S', (void)0)

fmi2Status fmi2GetDirectionalDerivative(fmi2Component instance, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    FORWARD(GetDirectionalDerivative, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    FORWARD(SetRealInputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    FORWARD(GetRealOutputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2DoStep(fmi2Component instance, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    CHECK(DoStep)
    switch (stepped_in_c(c_, currentCommunicationPoint, communicationStepSize)) {
    case 1:
        return fmi2OK; /* the slave's step, compiled, without Python */
    case -1:
        return fmi2Error;
    }
    CALL_TO(c_->state, DoStep, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint);
}

fmi2Status fmi2CancelStep(fmi2Component instance) { FORWARD(CancelStep); }

fmi2Status fmi2GetStatus(fmi2Component instance, const fmi2StatusKind s, fmi2Status *value)
{
    FORWARD(GetStatus, s, value);
}

fmi2Status fmi2GetRealStatus(fmi2Component instance, const fmi2StatusKind s, fmi2Real *value)
{
    FORWARD(GetRealStatus, s, value);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component instance, const fmi2StatusKind s, fmi2Integer *value)
{
    FORWARD(GetIntegerStatus, s, value);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component instance, const fmi2StatusKind s, fmi2Boolean *value)
{
    FORWARD(GetBooleanStatus, s, value);
}

fmi2Status fmi2GetStringStatus(fmi2Component instance, const fmi2StatusKind s, fmi2String *value)
{
    FORWARD(GetStringStatus, s, value);
}
