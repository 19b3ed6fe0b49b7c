/* The BouncingBall FMU's FMI 3.0 binary: a thin layer in front of pythonfmu3's binary.
 *
 * Like bouncingball_fmu_loader.c for FMI 2.0 (the Python it starts in a master without one, the
 * host check and the loading of the inner binary are shared: bouncingball_fmu_python.h), and for
 * what pythonfmu3 0.3.4's binary does not do:
 *   1. The FMI 3.0 state machine, for co-simulation and model exchange (ALLOWED, one row per call):
 *      a call outside its state, a value reference that is not a variable of the call's type, or an
 *      array size that does not match, gets fmi3Error and a log line, and changes nothing.
 *      pythonfmu3's binary keeps no state machine, and throws C++ exceptions nothing catches from
 *      the calls it does not implement (fmi3GetFloat32, fmi3GetClock, ...): those are answered here
 *      with fmi3Error and never reach it.
 *   2. Early return and event mode. pythonfmu3's fmi3DoStep reports the end of the step as
 *      lastSuccessfulTime, whatever the slave did, and never sets earlyReturn or
 *      eventHandlingNeeded. The slave (slave3.py) returns from do_step at the first impact or
 *      departure inside the step; this layer reads the time reached (the independent variable
 *      time, BB_TIME_REFERENCE) and either returns early (earlyReturn, lastSuccessfulTime = the event
 *      time, eventHandlingNeeded if the master uses event mode), or, where the master did not allow
 *      early return, steps on to the end of the communication step.
 *   3. A slave that logs an error during a call makes the call return fmi3Error; a warning it logs
 *      is only logged (finish() in bouncingball_fmu_python.h); a fatal status from pythonfmu3 ends
 *      this instance only (fmi3Error, then refused further calls).
 *   4. pythonfmu3's fmi3EnterInitializationMode drops startTime: it is passed to the slave first
 *      with fmi3SetTime, before initialisation (the slave takes it as the start time).
 *   5. pythonfmu3's fmi3UpdateDiscreteStates leaves an output it does not find on the slave's
 *      result as the master passed it: every output is set here first.
 * Built by bouncingball.fmu.build with the macros of bouncingball_fmu_python.h and
 * -DBB_VARIABLE_TYPES="RRI..." (the type of each value reference, FMI 3.0's variables included),
 * -DBB_TIME_REFERENCE=<value reference of time>, -DBB_CONTACT_REFERENCE=<value reference of contact>,
 * -DBB_STATES=2 and -DBB_EVENT_INDICATORS=1.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <libgen.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <wchar.h>

#include "fmi3Functions.h"

#if !defined(BB_VARIABLE_TYPES) || !defined(BB_TIME_REFERENCE) || !defined(BB_CONTACT_REFERENCE) || \
    !defined(BB_STATES) || !defined(BB_EVENT_INDICATORS) || BB_EVENT_INDICATORS != 1
#error "define BB_VARIABLE_TYPES, BB_TIME_REFERENCE, BB_CONTACT_REFERENCE, BB_STATES and BB_EVENT_INDICATORS (1)"
#endif

/* pythonfmu3's functions that are forwarded, loaded once per process (bouncingball_fmu_python.h) */
#define FMI_PREFIX fmi3
#define FMI_INSTANCE fmi3Instance
#define FMI_STATE_TYPE fmi3FMUState
#define GET_STATE GetFMUState
#define SET_STATE SetFMUState
#define FREE_STATE FreeFMUState
#define STATE_SIZE SerializedFMUStateSize
#define SERIALIZE_STATE SerializeFMUState
#define DESERIALIZE_STATE DeserializeFMUState
#define INNER_FUNCTIONS(X) \
    X(InstantiateModelExchange) X(InstantiateCoSimulation) X(FreeInstance) X(EnterInitializationMode) \
    X(ExitInitializationMode) X(Terminate) X(Reset) X(GetFloat64) X(GetInt32) X(GetBoolean) X(GetString) \
    X(SetFloat64) X(SetInt32) X(SetBoolean) X(SetString) X(GetFMUState) X(SetFMUState) X(FreeFMUState) \
    X(SerializedFMUStateSize) X(SerializeFMUState) X(DeserializeFMUState) X(DoStep) X(SetTime) \
    X(SetContinuousStates) X(GetContinuousStates) X(GetContinuousStateDerivatives) X(GetEventIndicators) \
    X(GetNominalsOfContinuousStates) X(UpdateDiscreteStates) X(CompletedIntegratorStep)
static const char *const TYPE_NAMES[] = {"Float64", "Int32", "Boolean", "String"};

/* FMI 3.0 states (FMI 3.0.2, sections 3.2 and 4.2); configuration, reconfiguration, intermediate
 * update and clock activation modes are never entered (no structural parameters, no clocks, no
 * intermediate update), nor the error states: a refused call changes nothing. */
typedef enum { INSTANTIATED, INITIALIZATION_MODE, EVENT_MODE, STEP_MODE, CONTINUOUS_TIME_MODE, TERMINATED } State;
static const char *const STATE_NAMES[] = {"instantiated", "initialization mode", "event mode", "step mode",
                                          "continuous-time mode", "terminated"};
typedef enum { CO_SIMULATION, MODEL_EXCHANGE } Interface;
static const char *const INTERFACE_NAMES[] = {"co-simulation", "model exchange"};
#define IN(state) (1u << (state))
#define CS (1u << 8) /* allowed in co-simulation */
#define ME (1u << 9) /* allowed in model exchange */
#define ANY (IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) | IN(STEP_MODE) | \
             IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | CS | ME)
#define INITIALIZED (IN(INITIALIZATION_MODE) | IN(EVENT_MODE) | IN(STEP_MODE) | IN(CONTINUOUS_TIME_MODE) | \
                     IN(TERMINATED) | CS | ME)
#define SETTABLE (IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) | IN(STEP_MODE) | \
                  IN(CONTINUOUS_TIME_MODE) | CS | ME)

/* The states (and interfaces) each call is allowed in. */
#define ALLOWED_EnterInitializationMode (IN(INSTANTIATED) | CS | ME)
#define ALLOWED_ExitInitializationMode (IN(INITIALIZATION_MODE) | CS | ME)
#define ALLOWED_EnterEventMode (IN(STEP_MODE) | IN(CONTINUOUS_TIME_MODE) | CS | ME)
#define ALLOWED_Terminate (IN(EVENT_MODE) | IN(STEP_MODE) | IN(CONTINUOUS_TIME_MODE) | CS | ME)
#define ALLOWED_Reset ANY
#define ALLOWED_GetFloat64 INITIALIZED
#define ALLOWED_GetInt32 INITIALIZED
#define ALLOWED_GetBoolean INITIALIZED
#define ALLOWED_GetString INITIALIZED
#define ALLOWED_SetFloat64 SETTABLE
#define ALLOWED_SetInt32 SETTABLE
#define ALLOWED_SetBoolean SETTABLE
#define ALLOWED_SetString SETTABLE
#define ALLOWED_GetFMUState ANY
#define ALLOWED_SetFMUState ANY
#define ALLOWED_SerializedFMUStateSize ANY
#define ALLOWED_SerializeFMUState ANY
#define ALLOWED_DeserializeFMUState ANY
#define ALLOWED_DoStep (IN(STEP_MODE) | CS)
#define ALLOWED_EnterStepMode (IN(EVENT_MODE) | CS)
#define ALLOWED_UpdateDiscreteStates (IN(EVENT_MODE) | CS | ME)
#define ALLOWED_EnterContinuousTimeMode (IN(EVENT_MODE) | ME)
#define ALLOWED_CompletedIntegratorStep (IN(CONTINUOUS_TIME_MODE) | ME)
#define ALLOWED_SetTime (IN(EVENT_MODE) | IN(CONTINUOUS_TIME_MODE) | ME)
#define ALLOWED_SetContinuousStates (IN(CONTINUOUS_TIME_MODE) | ME)
#define ALLOWED_GetContinuousStates (IN(EVENT_MODE) | IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | ME)
#define ALLOWED_GetContinuousStateDerivatives ALLOWED_GetContinuousStates
#define ALLOWED_GetEventIndicators ALLOWED_GetContinuousStates
#define ALLOWED_GetNominalsOfContinuousStates (ALLOWED_GetContinuousStates | IN(INSTANTIATED))
#define ALLOWED_GetNumberOfContinuousStates (ANY & ~CS)
#define ALLOWED_GetNumberOfEventIndicators (ANY & ~CS)

typedef struct Instance {
    fmi3Instance inner;
    fmi3InstanceEnvironment environment; /* the master's */
    fmi3LogMessageCallback logger;       /* the master's */
    char *name;
    fmi3Boolean logging_on;
    fmi3Boolean event_mode_used;
    fmi3Boolean early_return_allowed;
    fmi3Status worst; /* worst status logged during the current call */
    int dead;         /* pythonfmu3 returned fmi3Fatal: its instance is gone */
    int ended;        /* the compiled step raised: its state unknown, no further call taken */
    double *served_values; /* what is served without entering Python (bouncingball_fmu_python.h) */
    intptr_t *served_control;
    Interface interface;
    State state;
    struct Instance *next; /* the list of live instances */
} Instance;

#include "bouncingball_fmu_python.h"

static void tell(Instance *c, fmi3Status status, const char *category, const char *message)
{
    if (c->logger != NULL) {
        c->logger(c->environment, status, category, message);
    }
}

static int in_mode(const Instance *c, unsigned mask)
{
    return (mask & IN(c->state)) && (mask & (c->interface == CO_SIMULATION ? CS : ME));
}

static const char *mode_name(const Instance *c)
{
    static const char *const names[] = {"FMI 3.0 co-simulation", "FMI 3.0 model exchange"};
    return names[c->interface];
}

static int restorable(Instance *c, int state)
{
    if (state >= INSTANTIATED && state <= TERMINATED &&
        state != (c->interface == CO_SIMULATION ? CONTINUOUS_TIME_MODE : STEP_MODE)) {
        return 1;
    }
    say(c, fmi3Error, "fmi3DeserializeFMUState: these bytes are not a state of this FMU's %s: nothing was done",
        INTERFACE_NAMES[c->interface]);
    return 0;
}

/* The logger pythonfmu3 calls: remember the worst status, pass the message on. */
static void log_message(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category,
                        fmi3String message)
{
    Instance *c = (Instance *)environment;
    if (note(c, status)) {
        tell(c, status, category, message);
    }
}

/* 1 if every vr[i] is a scalar variable of the given type ('R', 'I', 'B' or 'S') and nValues matches. */
static int known_references(Instance *c, const char *function, const fmi3ValueReference vr[], size_t nvr,
                            size_t nValues, const void *values, char type)
{
    if ((nvr > 0 && (vr == NULL || values == NULL)) || nValues != nvr) {
        say(c, fmi3Error, "%s: %zu value references with %zu values%s (every variable of this FMU is a scalar): "
            "nothing was done", function, nvr, nValues, nvr > 0 && (vr == NULL || values == NULL) ? ", or NULL" : "");
        return 0;
    }
    return of_type(c, function, vr, nvr, type);
}

#define FORWARD_VALUES(function, type, serve, forward)                                                          \
    do {                                                                                                        \
        CHECK(function)                                                                                         \
        if (!known_references(c_, FMI_STRING(function), valueReferences, nValueReferences, nValues, values, type)) { \
            return fmi3Error;                                                                                   \
        }                                                                                                       \
        serve;                                                                                                  \
        forward(function, valueReferences, nValueReferences, values, nValues);                                  \
    } while (0)

/* A setter forwarded. */
#define SET_CALL(function, ...) CALL_TO(c_->state, function, ##__VA_ARGS__)

/* The getter and setter of one type of variable; the getter serves (SERVE_VALUES) what it can. */
#define VALUES_OF(type, ctype, letter, serve)                                                                 \
    fmi3Status fmi3Get##type(fmi3Instance instance, const fmi3ValueReference valueReferences[],               \
                             size_t nValueReferences, ctype values[], size_t nValues)                         \
    {                                                                                                         \
        FORWARD_VALUES(Get##type, letter, serve, READ_CALL);                                                  \
    }                                                                                                         \
    fmi3Status fmi3Set##type(fmi3Instance instance, const fmi3ValueReference valueReferences[],               \
                             size_t nValueReferences, const ctype values[], size_t nValues)                   \
    {                                                                                                         \
        FORWARD_VALUES(Set##type, letter, (void)0, SET_CALL);                                                 \
    }

/* An array argument of the model exchange calls: not NULL and of the model's size. */
static int right_size(Instance *c, const char *function, const void *array, size_t n, size_t expected)
{
    if (array == NULL || n != expected) {
        say(c, fmi3Error, "%s: an array of %zu values%s, where this FMU has %zu: nothing was done", function, n,
            array == NULL ? " (NULL)" : "", expected);
        return 0;
    }
    return 1;
}

#define FORWARD_ARRAY(function, array, n, expected)                  \
    do {                                                             \
        CHECK(function)                                              \
        if (!right_size(c_, "fmi3" #function, array, n, expected)) { \
            return fmi3Error;                                        \
        }                                                            \
        CALL_TO(c_->state, function, array, n);                      \
    } while (0)

const char *fmi3GetVersion(void) { return fmi3Version; }

static Instance *instantiate(Interface interface, fmi3String instanceName, fmi3InstanceEnvironment environment,
                             fmi3LogMessageCallback logMessage, fmi3Boolean loggingOn)
{
    char problem[4096];
    Instance *c;
    if (!can_instantiate(problem, sizeof problem)) {
        if (logMessage != NULL) {
            logMessage(environment, fmi3Error, "logStatusError", problem);
        }
        return NULL;
    }
    c = new_instance(instanceName, loggingOn);
    if (c == NULL) {
        return NULL;
    }
    c->environment = environment;
    c->logger = logMessage;
    c->interface = interface;
    return c;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    Instance *c = instantiate(MODEL_EXCHANGE, instanceName, instanceEnvironment, logMessage, loggingOn);
    if (c == NULL) {
        return NULL;
    }
    MAKING(c, c->inner = inner.InstantiateModelExchange(instanceName, instantiationToken, resourcePath, visible,
                                                        fmi3True, c, log_message));
    return keep(c);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Instance *c;
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate; /* this FMU never calls it: it has no intermediate update */
    if (nRequiredIntermediateVariables > 0) {
        if (logMessage != NULL) {
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "fmi3InstantiateCoSimulation: this FMU has no intermediate update, so no required "
                       "intermediate variables");
        }
        return NULL;
    }
    c = instantiate(CO_SIMULATION, instanceName, instanceEnvironment, logMessage, loggingOn);
    if (c == NULL) {
        return NULL;
    }
    c->event_mode_used = eventModeUsed;
    c->early_return_allowed = earlyReturnAllowed;
    MAKING(c, c->inner = inner.InstantiateCoSimulation(instanceName, instantiationToken, resourcePath, visible,
                                                       fmi3True, eventModeUsed, earlyReturnAllowed, NULL, 0, c,
                                                       log_message, NULL));
    return keep(c);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage != NULL) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "this FMU offers co-simulation and model exchange, not scheduled execution");
    }
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { free_instance(instance); }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    (void)nCategories, (void)categories;
    return set_logging(instance, loggingOn);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Instance *c = (Instance *)instance;
    fmi3Status status;
    if (c == NULL || !allowed(c, "fmi3EnterInitializationMode", ALLOWED_EnterInitializationMode)) {
        return fmi3Error;
    }
    if (!isfinite(startTime)) {
        say(c, fmi3Error, "fmi3EnterInitializationMode: startTime = %g s is not allowed: it must be finite", startTime);
        return fmi3Error;
    }
    if (toleranceDefined && tolerance < 1e-3) {
        say(c, fmi3OK, "tolerance = %g (fmi3EnterInitializationMode) is not used: set the parameter rtol", tolerance);
    }
    unserve(c);
    status = finish(c, inner.SetTime(c->inner, startTime)); /* the start time: pythonfmu3 drops it below */
    if (status > fmi3Warning) {
        return status;
    }
    c->worst = fmi3OK;
    status = finish(c, inner.EnterInitializationMode(c->inner, toleranceDefined, tolerance, startTime,
                                                     stopTimeDefined, stopTime));
    if (status <= fmi3Warning) {
        c->state = INITIALIZATION_MODE;
    }
    return status;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Instance *c = (Instance *)instance;
    State next = STEP_MODE;
    if (c != NULL && (c->interface == MODEL_EXCHANGE || c->event_mode_used)) {
        next = EVENT_MODE;
    }
    FORWARD_TO(next, ExitInitializationMode);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    CHECK(EnterEventMode)
    if (c_->interface == CO_SIMULATION && !c_->event_mode_used) {
        say(c_, fmi3Error, "fmi3EnterEventMode: this instance was instantiated with eventModeUsed = false");
        return fmi3Error;
    }
    c_->state = EVENT_MODE; /* the slave's mode has switched at the event already: nothing to forward */
    return fmi3OK;
}

/* A mode the slave has no part in: only the state machine moves. */
#define ENTER(mode, function)   \
    do {                        \
        CHECK(function)         \
        c_->state = (mode);     \
        return fmi3OK;          \
    } while (0)

fmi3Status fmi3EnterStepMode(fmi3Instance instance) { ENTER(STEP_MODE, EnterStepMode); }

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { ENTER(CONTINUOUS_TIME_MODE, EnterContinuousTimeMode); }

fmi3Status fmi3Terminate(fmi3Instance instance) { FORWARD_TO(TERMINATED, Terminate); }

fmi3Status fmi3Reset(fmi3Instance instance) { return reset_instance(instance); }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    Instance *c = (Instance *)instance;
    if (c == NULL || !allowed(c, "fmi3UpdateDiscreteStates", ALLOWED_UpdateDiscreteStates)) {
        return fmi3Error;
    }
    if (!discreteStatesNeedUpdate || !terminateSimulation || !nominalsOfContinuousStatesChanged ||
        !valuesOfContinuousStatesChanged || !nextEventTimeDefined || !nextEventTime) {
        say(c, fmi3Error, "fmi3UpdateDiscreteStates: an output argument is NULL: nothing was done");
        return fmi3Error;
    }
    *discreteStatesNeedUpdate = *terminateSimulation = *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
    if (c->interface == CO_SIMULATION) {
        return fmi3OK; /* the co-simulation slave switches its mode inside fmi3DoStep */
    }
    unserve(c);
    return finish(c, inner.UpdateDiscreteStates(c->inner, discreteStatesNeedUpdate, terminateSimulation,
                                                nominalsOfContinuousStatesChanged, valuesOfContinuousStatesChanged,
                                                nextEventTimeDefined, nextEventTime));
}

/* --- variables ------------------------------------------------------------------------------------ */
#define AS_BOOLEAN(x) ((x) != 0.0)
VALUES_OF(Float64, fmi3Float64, 'R', SERVE_VALUES((fmi3Float64), valueReferences, nValueReferences, values))
VALUES_OF(Int32, fmi3Int32, 'I', SERVE_VALUES((fmi3Int32), valueReferences, nValueReferences, values))
VALUES_OF(Boolean, fmi3Boolean, 'B', SERVE_VALUES(AS_BOOLEAN, valueReferences, nValueReferences, values))
VALUES_OF(String, fmi3String, 'S', (void)0)

/* Calls for what this FMU does not have: answered here, never forwarded (pythonfmu3 throws from them). They
 * ignore their arguments. */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
static fmi3Status not_provided(fmi3Instance instance, const char *function, const char *what)
{
    if (instance != NULL) {
        say((Instance *)instance, fmi3Error, "%s: this FMU has %s: nothing was done", function, what);
    }
    return fmi3Error;
}

#define NO_VARIABLES_OF(type, ctype)                                                                            \
    fmi3Status fmi3Get##type(fmi3Instance instance, const fmi3ValueReference valueReferences[],                 \
                             size_t nValueReferences, ctype values[], size_t nValues)                           \
    {                                                                                                           \
        return not_provided(instance, "fmi3Get" #type, "no variable of type " #type);                           \
    }                                                                                                           \
    fmi3Status fmi3Set##type(fmi3Instance instance, const fmi3ValueReference valueReferences[],                 \
                             size_t nValueReferences, const ctype values[], size_t nValues)                     \
    {                                                                                                           \
        return not_provided(instance, "fmi3Set" #type, "no variable of type " #type);                           \
    }

NO_VARIABLES_OF(Float32, fmi3Float32)
NO_VARIABLES_OF(Int8, fmi3Int8)
NO_VARIABLES_OF(UInt8, fmi3UInt8)
NO_VARIABLES_OF(Int16, fmi3Int16)
NO_VARIABLES_OF(UInt16, fmi3UInt16)
NO_VARIABLES_OF(UInt32, fmi3UInt32)
NO_VARIABLES_OF(Int64, fmi3Int64)
NO_VARIABLES_OF(UInt64, fmi3UInt64)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    return not_provided(instance, "fmi3GetBinary", "no variable of type Binary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    return not_provided(instance, "fmi3SetBinary", "no variable of type Binary");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[])
{
    return not_provided(instance, "fmi3GetClock", "no clocks");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[])
{
    return not_provided(instance, "fmi3SetClock", "no clocks");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    return not_provided(instance, "fmi3GetNumberOfVariableDependencies", "no variable dependencies to give");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
    return not_provided(instance, "fmi3GetVariableDependencies", "no variable dependencies to give");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return not_provided(instance, "fmi3GetDirectionalDerivative", "no directional derivatives");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return not_provided(instance, "fmi3GetAdjointDerivative", "no adjoint derivatives");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues)
{
    return not_provided(instance, "fmi3GetOutputDerivatives", "no output derivatives");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{
    return not_provided(instance, "fmi3EnterConfigurationMode", "no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{
    return not_provided(instance, "fmi3ExitConfigurationMode", "no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    return not_provided(instance, "fmi3GetIntervalDecimal", "no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[])
{
    return not_provided(instance, "fmi3GetIntervalFraction", "no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    return not_provided(instance, "fmi3GetShiftDecimal", "no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    return not_provided(instance, "fmi3GetShiftFraction", "no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    return not_provided(instance, "fmi3SetIntervalDecimal", "no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    return not_provided(instance, "fmi3SetIntervalFraction", "no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    return not_provided(instance, "fmi3SetShiftDecimal", "no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    return not_provided(instance, "fmi3SetShiftFraction", "no clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    return not_provided(instance, "fmi3EvaluateDiscreteStates", "no clocks");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    return not_provided(instance, "fmi3ActivateModelPartition", "no scheduled execution");
}
#pragma GCC diagnostic pop

/* --- co-simulation ---------------------------------------------------------------------------------- */
/* The time the slave has reached (the independent variable), or NAN with c->worst raised. */
static fmi3Float64 slave_time(Instance *c)
{
    const fmi3ValueReference time_reference = BB_TIME_REFERENCE;
    fmi3Float64 time = NAN;
    if (served_ready(c)) {
        return c->served_values[time_reference];
    }
    if (finish(c, inner.GetFloat64(c->inner, &time_reference, 1, &time, 1)) > fmi3Warning) {
        return NAN;
    }
    return time;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    Instance *c = (Instance *)instance;
    fmi3Float64 end = currentCommunicationPoint + communicationStepSize, t = currentCommunicationPoint;
    fmi3Float64 step = communicationStepSize, reached, ignored_time;
    fmi3Boolean ignored_event, ignored_early, terminate = fmi3False;
    fmi3Status status = fmi3OK;
    int stalled = 0;
    if (c == NULL || !allowed(c, "fmi3DoStep", ALLOWED_DoStep)) {
        return fmi3Error;
    }
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        say(c, fmi3Error, "fmi3DoStep: an output argument is NULL: nothing was done");
        return fmi3Error;
    }
    *eventHandlingNeeded = *terminateSimulation = *earlyReturn = fmi3False;
    *lastSuccessfulTime = currentCommunicationPoint;
    for (;;) {
        /* The slave returns at the first impact or departure inside the step, or at its end: compiled, without
         * Python, where it can (stepped_in_c). */
        c->worst = fmi3OK;
        int taken = stepped_in_c(c, t, step);
        if (taken < 0) {
            return fmi3Error;
        }
        if (!taken) {
            unserve(c);
            fmi3Status s = finish(c, inner.DoStep(c->inner, t, step, noSetFMUStatePriorToCurrentPoint,
                                                  &ignored_event, &terminate, &ignored_early, &ignored_time));
            status = s > status ? s : status;
            if (status > fmi3Warning) {
                return status; /* the slave refused the step: it is still at *lastSuccessfulTime */
            }
        }
        c->worst = fmi3OK;
        reached = slave_time(c);
        if (isnan(reached)) {
            return fmi3Error;
        }
        *lastSuccessfulTime = reached;
        /* The end of the step, to the rounding of t + (end - t). */
        if (reached >= end || end - reached <= 4.0 * fabs(end) * 2.220446049250313e-16) {
            break;
        }
        stalled = reached <= t ? stalled + 1 : 0;
        if (stalled > 1) { /* one event at t itself is possible, not two */
            say(c, fmi3Error, "fmi3DoStep: the slave made no progress from t = %.17g s", t);
            return fmi3Error;
        }
        if (c->early_return_allowed) {
            *earlyReturn = fmi3True;
            *eventHandlingNeeded = c->event_mode_used;
            break;
        }
        t = reached;
        step = end - t;
    }
    *terminateSimulation = terminate;
    return status;
}

/* --- model exchange ---------------------------------------------------------------------------------- */
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    CHECK(SetTime)
    if (!isfinite(time)) {
        say(c_, fmi3Error, "fmi3SetTime: time = %g s is not allowed: it must be finite", time);
        return fmi3Error;
    }
    CALL_TO(c_->state, SetTime, time);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    FORWARD_ARRAY(SetContinuousStates, continuousStates, nContinuousStates, BB_STATES);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates)
{
    FORWARD_ARRAY(GetContinuousStates, continuousStates, nContinuousStates, BB_STATES);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates)
{
    FORWARD_ARRAY(GetContinuousStateDerivatives, derivatives, nContinuousStates, BB_STATES);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators)
{
    FORWARD_ARRAY(GetEventIndicators, eventIndicators, nEventIndicators, BB_EVENT_INDICATORS);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates)
{
    FORWARD_ARRAY(GetNominalsOfContinuousStates, nominals, nContinuousStates, BB_STATES);
}

static fmi3Status count(fmi3Instance instance, const char *function, unsigned mask, size_t *n, size_t value)
{
    Instance *c = (Instance *)instance;
    if (c == NULL || !allowed(c, function, mask)) {
        return fmi3Error;
    }
    if (n == NULL) {
        say(c, fmi3Error, "%s: the output argument is NULL", function);
        return fmi3Error;
    }
    *n = value;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    return count(instance, "fmi3GetNumberOfContinuousStates", ALLOWED_GetNumberOfContinuousStates, nContinuousStates,
                 BB_STATES);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    return count(instance, "fmi3GetNumberOfEventIndicators", ALLOWED_GetNumberOfEventIndicators, nEventIndicators,
                 BB_EVENT_INDICATORS);
}

/* Whether the state the master's integrator reached contradicts the mode: an impact or departure it stepped
 * over without seeing the event indicator change sign (a bounce shorter than its step). The event indicator
 * is >= 0 out of contact and <= 0 in it (the rigid law's rest: F_ext/m - g), so its sign against the output
 * contact tells; the FMU then asks for event mode, where the switch is made. */
static int missed_event(Instance *c)
{
    const fmi3ValueReference contact_reference = BB_CONTACT_REFERENCE;
    fmi3Boolean contact = fmi3False;
    fmi3Float64 indicator = 0.0;
    if (finish(c, inner.GetBoolean(c->inner, &contact_reference, 1, &contact, 1)) > fmi3Warning ||
        finish(c, inner.GetEventIndicators(c->inner, &indicator, 1)) > fmi3Warning) {
        return 0;
    }
    return contact ? indicator > 0.0 : indicator < 0.0;
}

/* Tells the slave that the master accepted the state it set: the slave measures the master's error there
 * (master_error.py). pythonfmu3 does not forward fmi3CompletedIntegratorStep to Python, so the call is a
 * read of time twice, which the slave answers (slave3.BouncingBall.get_float64) after measuring. */
static void completed_step(Instance *c)
{
    const fmi3ValueReference references[2] = {BB_TIME_REFERENCE, BB_TIME_REFERENCE};
    fmi3Float64 times[2] = {NAN, NAN};
    finish(c, inner.GetFloat64(c->inner, references, 2, times, 2));
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    CHECK(CompletedIntegratorStep)
    if (enterEventMode == NULL || terminateSimulation == NULL) {
        say(c_, fmi3Error, "fmi3CompletedIntegratorStep: an output argument is NULL");
        return fmi3Error;
    }
    fmi3Status status = finish(c_, inner.CompletedIntegratorStep(c_->inner, noSetFMUStatePriorToCurrentPoint,
                                                                 enterEventMode, terminateSimulation));
    if (status <= fmi3Warning) {
        completed_step(c_);
    }
    if (status <= fmi3Warning && !*enterEventMode && missed_event(c_)) {
        *enterEventMode = fmi3True;
    }
    return finish(c_, status);
}
