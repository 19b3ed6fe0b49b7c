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
 *      Here, the status of each call is the worst of what pythonfmu returns and what the slave
 *      logged during the call, so a slave that logs an error makes the call return fmi2Error.
 *      A fatal status from pythonfmu becomes fmi2Error for this instance only, which is then
 *      refused further calls (pythonfmu has already released its Python objects).
 *   3. pythonfmu 0.7.0 releases its interpreter state twice at process exit; the loader
 *      releases it once, first (see load()).
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

/* pythonfmu's functions, loaded once per process */
#define INNER_FUNCTIONS(X) \
    X(SetDebugLogging) X(Instantiate) X(FreeInstance) X(SetupExperiment) X(EnterInitializationMode) \
    X(ExitInitializationMode) X(Terminate) X(Reset) X(GetReal) X(GetInteger) X(GetBoolean) X(GetString) \
    X(SetReal) X(SetInteger) X(SetBoolean) X(SetString) X(GetFMUstate) X(SetFMUstate) X(FreeFMUstate) \
    X(SerializedFMUstateSize) X(SerializeFMUstate) X(DeSerializeFMUstate) X(GetDirectionalDerivative) \
    X(SetRealInputDerivatives) X(GetRealOutputDerivatives) X(DoStep) X(CancelStep) X(GetStatus) \
    X(GetRealStatus) X(GetIntegerStatus) X(GetBooleanStatus) X(GetStringStatus)

#define DECLARE(name) fmi2##name##TYPE *name;
static struct {
    INNER_FUNCTIONS(DECLARE)
} inner;


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
    State state;
    struct Instance *next;        /* the list of live instances */
} Instance;

#include "bouncingball_fmu_python.h"

static pthread_once_t load_once = PTHREAD_ONCE_INIT;

static void load(void)
{
    void *library = open_inner();
    if (library == NULL) {
        return;
    }
#define LOAD(name) *(void **)&inner.name = symbol(library, "fmi2" #name);
    INNER_FUNCTIONS(LOAD)
}

/* The logger pythonfmu calls: remember the worst status, pass the message on. pythonfmu always
 * logs here (it is instantiated with logging on); messages with status fmi2OK reach the master
 * only while it has logging on, warnings and errors always. */
static void log_message(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status,
                        fmi2String category, fmi2String message, ...)
{
    Instance *c = (Instance *)environment;
    if (status > c->worst) {
        c->worst = status;
    }
    if ((status != fmi2OK || c->logging_on) && c->master.logger != NULL) {
        c->master.logger(c->master.componentEnvironment, name, status, category, "%s", message);
    }
}

static fmi2Status refuse(Instance *c, const char *function)
{
    if (c->master.logger != NULL) {
        c->master.logger(c->master.componentEnvironment, c->name, fmi2Error, "logStatusError",
                         "%s refused: an earlier error ended this instance", function);
    }
    return fmi2Error;
}

static fmi2Status not_allowed(Instance *c, const char *function)
{
    if (c->master.logger != NULL) {
        c->master.logger(c->master.componentEnvironment, c->name, fmi2Error, "logStatusError",
                         "%s is not allowed in state %s (FMI 2.0 co-simulation): nothing was done", function,
                         STATE_NAMES[c->state]);
    }
    return fmi2Error;
}

/* 1 if every vr[i] is a variable of the given type ('R', 'I', 'B' or 'S'); else logs the first that is not. */
static int known_references(Instance *c, const char *function, const fmi2ValueReference vr[], size_t nvr, char type)
{
    static const char types[] = BB_VARIABLE_TYPES;
    static const char *const type_names[] = {"Real", "Integer", "Boolean", "String"};
    const char *type_name = type_names[strchr("RIBS", type) - "RIBS"];
    if (nvr > 0 && vr == NULL) {
        if (c->master.logger != NULL) {
            c->master.logger(c->master.componentEnvironment, c->name, fmi2Error, "logStatusError",
                             "%s: vr is NULL for %zu value references", function, nvr);
        }
        return 0;
    }
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= sizeof types - 1 || types[vr[i]] != type) {
            if (c->master.logger != NULL) {
                c->master.logger(c->master.componentEnvironment, c->name, fmi2Error, "logStatusError",
                                 "%s: value reference %u is not a variable of type %s in this FMU: nothing was done",
                                 function, (unsigned)vr[i], type_name);
            }
            return 0;
        }
    }
    return 1;
}

static fmi2Status finish(Instance *c, fmi2Status status)
{
    if (status == fmi2Fatal) {
        c->dead = 1;
        return fmi2Error;
    }
    if (c->worst > status) {
        status = c->worst > fmi2Error ? fmi2Error : c->worst;
    }
    return status;
}

/* Forward one call to pythonfmu if the state machine allows it, return the combined status, and move
 * the instance to state `next` if it succeeded (GNU ##__VA_ARGS__: gcc and clang drop the comma for
 * calls without arguments). */
#define FORWARD_TO(next, function, ...)                                 \
    do {                                                                \
        Instance *c_ = (Instance *)c;                                   \
        if (c_ == NULL) {                                               \
            return fmi2Error;                                           \
        }                                                               \
        if (c_->dead) {                                                 \
            return refuse(c_, "fmi2" #function);                        \
        }                                                               \
        if (!(ALLOWED_##function & IN(c_->state))) {                    \
            return not_allowed(c_, "fmi2" #function);                   \
        }                                                               \
        c_->worst = fmi2OK;                                             \
        fmi2Status status_ = finish(c_, inner.function(c_->inner, ##__VA_ARGS__)); \
        if (status_ <= fmi2Warning) {                                   \
            c_->state = (next);                                         \
        }                                                               \
        return status_;                                                 \
    } while (0)

/* A call that leaves the state as it is. */
#define FORWARD(function, ...) FORWARD_TO(c_->state, function, ##__VA_ARGS__)

/* FORWARD for a getter or setter of one type: its value references are checked first. */
#define FORWARD_VALUES(function, type, vr, nvr, ...)                    \
    do {                                                                \
        Instance *c_ = (Instance *)c;                                   \
        if (c_ != NULL && !c_->dead && (ALLOWED_##function & IN(c_->state)) && \
            !known_references(c_, "fmi2" #function, vr, nvr, type)) {   \
            return fmi2Error;                                           \
        }                                                               \
        FORWARD(function, vr, nvr, ##__VA_ARGS__);                      \
    } while (0)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    char problem[4096];
    Instance *c;
    pthread_once(&load_once, load);
    if (load_error[0] != '\0') {
        if (functions != NULL && functions->logger != NULL) {
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError", "%s",
                              load_error);
        }
        return NULL;
    }
    if (functions == NULL) {
        return NULL; /* FMI requires the callbacks; without a logger there is no one to tell */
    }
    if (!host_ready(problem, sizeof problem)) {
        if (functions->logger != NULL) {
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError", "%s",
                              problem);
        }
        return NULL;
    }
    c = calloc(1, sizeof *c);
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
    c->name = strdup(instanceName != NULL ? instanceName : "");
    if (c->name == NULL) {
        free(c);
        return NULL;
    }
    c->logging_on = loggingOn;
    c->state = INSTANTIATED;
    c->inner = inner.Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, &c->own, visible, fmi2True);
    if (c->inner == NULL) {
        free(c->name);
        free(c);
        return NULL;
    }
    link_live(c);
    return c;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *instance = (Instance *)c;
    /* A second call for the same instance is undefined by the standard: do nothing rather than
     * free it twice (its memory, and with it the master's logger, is gone: nothing to log to). */
    if (instance == NULL || !unlink_live(instance)) {
        return;
    }
    if (!instance->dead) { /* a dead pythonfmu instance has released its objects already */
        inner.FreeInstance(instance->inner);
    }
    free(instance->name);
    free(instance);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories;
    (void)categories;
    if (c == NULL) {
        return fmi2Error;
    }
    ((Instance *)c)->logging_on = loggingOn; /* pythonfmu keeps logging everything to us */
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    FORWARD(SetupExperiment, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { FORWARD_TO(INITIALIZATION_MODE, EnterInitializationMode); }

fmi2Status fmi2ExitInitializationMode(fmi2Component c) { FORWARD_TO(STEP_COMPLETE, ExitInitializationMode); }

fmi2Status fmi2Terminate(fmi2Component c) { FORWARD_TO(TERMINATED, Terminate); }

fmi2Status fmi2Reset(fmi2Component c) { FORWARD_TO(INSTANTIATED, Reset); }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    FORWARD_VALUES(GetReal, 'R', vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    FORWARD_VALUES(GetInteger, 'I', vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    FORWARD_VALUES(GetBoolean, 'B', vr, nvr, value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    FORWARD_VALUES(GetString, 'S', vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    FORWARD_VALUES(SetReal, 'R', vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    FORWARD_VALUES(SetInteger, 'I', vr, nvr, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    FORWARD_VALUES(SetBoolean, 'B', vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    FORWARD_VALUES(SetString, 'S', vr, nvr, value);
}

/* An FMU state (FmuState, bouncingball_fmu_python.h): a fresh instance given the state of an initialised one
 * is initialised. */
static fmi2Status get_state_inner(fmi2Component c, fmi2FMUstate *FMUstate) { FORWARD(GetFMUstate, FMUstate); }

static fmi2Status size_inner(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    FORWARD(SerializedFMUstateSize, FMUstate, size);
}

static fmi2Status serialize_inner(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte bytes[], size_t size)
{
    FORWARD(SerializeFMUstate, FMUstate, bytes, size);
}

static fmi2Status deserialize_inner(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *FMUstate)
{
    FORWARD(DeSerializeFMUstate, bytes, size, FMUstate);
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    FmuState *saved;
    if (c == NULL || FMUstate == NULL) {
        return fmi2Error;
    }
    saved = state_to_fill(FMUstate);
    if (saved == NULL) {
        return fmi2Error;
    }
    return into_state(get_state_inner(c, &saved->inner), saved, FMUstate, ((Instance *)c)->state);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    FmuState *saved = (FmuState *)FMUstate;
    if (saved == NULL) {
        return fmi2Error;
    }
    FORWARD_TO(saved->state, SetFMUstate, saved->inner);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *instance = (Instance *)c;
    FmuState *saved;
    fmi2Status status = fmi2OK;
    if (instance == NULL || FMUstate == NULL) {
        return fmi2Error;
    }
    saved = (FmuState *)*FMUstate;
    if (saved == NULL) {
        return fmi2OK; /* freeing nothing is allowed */
    }
    if (!instance->dead) {
        instance->worst = fmi2OK;
        status = finish(instance, inner.FreeFMUstate(instance->inner, &saved->inner));
    }
    free(saved);
    *FMUstate = NULL;
    return status;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    FmuState *saved = (FmuState *)FMUstate;
    fmi2Status status;
    if (saved == NULL || size == NULL) {
        return fmi2Error;
    }
    status = size_inner(c, saved->inner, size);
    if (status <= fmi2Warning) {
        *size += 1;
    }
    return status;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    FmuState *saved = (FmuState *)FMUstate;
    if (saved == NULL || serializedState == NULL || size < 1) {
        return fmi2Error;
    }
    serializedState[0] = (fmi2Byte)saved->state;
    return serialize_inner(c, saved->inner, serializedState + 1, size - 1);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    Instance *instance = (Instance *)c;
    FmuState *saved;
    if (instance == NULL || FMUstate == NULL) {
        return fmi2Error;
    }
    if (serializedState == NULL || size < 1 || (unsigned char)serializedState[0] > TERMINATED) {
        if (instance->master.logger != NULL) {
            instance->master.logger(instance->master.componentEnvironment, instance->name, fmi2Error,
                                    "logStatusError", "fmi2DeSerializeFMUstate: these bytes are not a state of this "
                                    "FMU: nothing was done");
        }
        return fmi2Error;
    }
    saved = state_to_fill(FMUstate);
    if (saved == NULL) {
        return fmi2Error;
    }
    return into_state(deserialize_inner(c, serializedState + 1, size - 1, &saved->inner), saved, FMUstate,
                      (State)(unsigned char)serializedState[0]);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    FORWARD(GetDirectionalDerivative, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    FORWARD(SetRealInputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    FORWARD(GetRealOutputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    FORWARD(DoStep, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint);
}

fmi2Status fmi2CancelStep(fmi2Component c) { FORWARD(CancelStep); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    FORWARD(GetStatus, s, value);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    FORWARD(GetRealStatus, s, value);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    FORWARD(GetIntegerStatus, s, value);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    FORWARD(GetBooleanStatus, s, value);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    FORWARD(GetStringStatus, s, value);
}
