/* The part of the BouncingBall FMU's binaries that does not depend on the FMI version: the Python
 * that runs pythonfmu (or pythonfmu3), the loading of their binary, the check of the host's Python,
 * the instances' life, the status of a forwarded call, and the FMU state calls. Included by
 * bouncingball_fmu_loader.c (FMI 2.0) and bouncingball_fmu3_loader.c (FMI 3.0), which define the
 * macros they describe (BB_LIBPYTHON, BB_PYTHON, BB_INNER, BB_PYTHON_VERSION, BB_HOST_CHECK,
 * BB_VARIABLE_TYPES), include <dlfcn.h>, <libgen.h>, <pthread.h>, <stdarg.h>, <stdint.h>, <stdio.h>, <stdlib.h>,
 * <string.h>, <unistd.h>, <wchar.h> and their FMI headers, and define first:
 *   FMI_PREFIX            fmi2 or fmi3: FMI(Status) is fmi2Status or fmi3Status (the statuses are numbered alike);
 *   FMI_INSTANCE, FMI_STATE_TYPE  the types of an instance and of an FMU state (fmi2Component, fmi2FMUstate);
 *   GET_STATE, SET_STATE, FREE_STATE, STATE_SIZE, SERIALIZE_STATE, DESERIALIZE_STATE  how the version
 *                         spells the FMU state calls (GetFMUstate, ..., DeSerializeFMUstate);
 *   INNER_FUNCTIONS(X)    the inner binary's functions to load, by name without the prefix;
 *   State                 an enum whose first value is INSTANTIATED, STATE_NAMES, IN(state) (a mask bit)
 *                         and ALLOWED_<call> (the mask of the states each forwarded call is allowed in);
 *   TYPE_NAMES            the version's names of the variable types R, I, B and S;
 *   Instance              with inner, name, logging_on, worst, dead, ended, state, `double *served_values`,
 *                         `intptr_t *served_control` and `struct Instance *next`;
 * and, after the #include, the functions declared below as the loader's.
 */
#ifndef BOUNCINGBALL_FMU_PYTHON_H
#define BOUNCINGBALL_FMU_PYTHON_H

#define FMI_PASTE_(a, b) a##b
#define FMI_PASTE(a, b) FMI_PASTE_(a, b)
#define FMI(name) FMI_PASTE(FMI_PREFIX, name)
#define FMI_QUOTE_(text) #text
#define FMI_QUOTE(text) FMI_QUOTE_(text)
#define FMI_STRING(name) FMI_QUOTE(FMI(name)) /* FMI_STRING(DoStep): "fmi2DoStep" */

/* Defined by the loader: pass one line to the master's logger (if it has one), */
static void tell(Instance *c, FMI(Status) status, const char *category, const char *message);
/* 1 if a call allowed in mask may run in c's state (and interface), */
static int in_mode(const Instance *c, unsigned mask);
/* what c runs, as "FMI 2.0 co-simulation", */
static const char *mode_name(const Instance *c);
/* 1 if state (a serialized state's first byte, -1 if it has none) is one c may be restored to; else logs why, 0. */
static int restorable(Instance *c, int state);

/* The inner binary's functions, loaded once per process */
#define DECLARE(name) FMI(name##TYPE) *name;
static struct {
    INNER_FUNCTIONS(DECLARE)
} inner;

static void (*release_python_state)(void); /* pythonfmu's finalizePythonInterpreter */

/* --- what the loader serves without entering Python (fmu/c_layer.py, the slave's side) ----------------------
 * The slave's values by value reference (Integers and Booleans as doubles), and the control slots: READY (the
 * values are the slave's current ones and STEP may be called), STEP (0, or the address of the compiled doStep,
 * solvers/engines/c_entry.py, which writes the values it changes), CONTEXT (STEP's first argument), BEGUN (what STEP
 * left for the slave to finish, read by it at its next do_step: 0 for nothing), and the descriptors of the files
 * SUNDIALS writes its warnings to (LOG0, LOG1; -1 for none) with their sizes when the slave last read them
 * (SIZE0, SIZE1). The slave owns the memory and sets READY at the end of each step it took; the loader clears it
 * before it forwards any call but a getter (unserve), so that what a set, a reset or a restored state changes is
 * never served stale. The slave hands its memory over (bouncingball_serve) while it is being made: in
 * fmi2Instantiate / fmi3Instantiate* and Reset, where `linking` is the instance. */
enum { SERVED_READY, SERVED_STEP, SERVED_CONTEXT, SERVED_BEGUN, SERVED_LOG0, SERVED_LOG1, SERVED_SIZE0, SERVED_SIZE1,
       SERVED_SLOTS };
enum { STEP_RAISED, STEP_NOT_TAKEN, STEP_TAKEN, STEP_TAKEN_WITH_CVODE, STEP_FINISH = 16 }; /* c_entry's RAISED, ... */
typedef int (*InStep)(intptr_t context, double current_time, double step_size);

static __thread Instance *linking;

/* Called by the slave (ctypes) while it is being made: its memory for the instance being made; 1 if taken. */
__attribute__((visibility("default"))) int bouncingball_serve(double *values, intptr_t *control, size_t n)
{
    if (linking == NULL || values == NULL || control == NULL || n != sizeof BB_VARIABLE_TYPES - 1) {
        return 0;
    }
    control[SERVED_READY] = 0;
    linking->served_values = values;
    linking->served_control = control;
    return 1;
}

static int served_ready(const Instance *c) { return c->served_control != NULL && c->served_control[SERVED_READY]; }

/* Before any call forwarded to the slave: its values may change, or its memory go (Reset, FreeInstance). */
static void unserve(Instance *c)
{
    if (c->served_control != NULL) {
        c->served_control[SERVED_READY] = 0;
    }
}

/* The slave is made anew (Instantiate, Reset): the old one's memory is not to be read again; the new one hands its
 * own over while `call` makes it. */
#define MAKING(c, call)                 \
    do {                                \
        unserve(c);                     \
        (c)->served_values = NULL;      \
        (c)->served_control = NULL;     \
        linking = (c);                  \
        call;                           \
        linking = NULL;                 \
    } while (0)

static void say(Instance *c, FMI(Status) status, const char *format, ...) __attribute__((format(printf, 3, 4)));

/* 1 if SUNDIALS wrote to a warnings file since the slave last read it. */
static int sundials_wrote(const intptr_t *control)
{
    for (int i = 0; i < 2; i++) {
        int descriptor = (int)control[SERVED_LOG0 + i];
        if (descriptor >= 0 && lseek(descriptor, 0, SEEK_END) != (off_t)control[SERVED_SIZE0 + i]) {
            return 1;
        }
    }
    return 0;
}

/* The slave's compiled doStep from current_time by step_size, where it is served: 1 if the step is taken and
 * nothing is left to do (the values are current); 0 if the slave takes the step, or finishes what the compiled
 * step began (BEGUN: the failure to word, the warnings to read or check); -1 if the compiled code raised (the
 * instance ended, the error logged). */
static int stepped_in_c(Instance *c, double current_time, double step_size)
{
    InStep step;
    int left;
    if (!served_ready(c) || c->served_control[SERVED_STEP] == 0) {
        return 0;
    }
    *(void **)&step = (void *)c->served_control[SERVED_STEP];
    left = step(c->served_control[SERVED_CONTEXT], current_time, step_size);
    if (left == STEP_RAISED) { /* its state unknown: as where the slave's own step raises, the instance ends */
        c->ended = 1;
        unserve(c);
        say(c, FMI(Error), "the compiled engine raised inside the step from t = %.17g s (numba's engine prints the "
            "exception on stderr; the native engine keeps none of it): the instance's state is unknown, and it takes "
            "no further call", current_time);
        return -1;
    }
    if (left == STEP_TAKEN || (left == STEP_TAKEN_WITH_CVODE && !sundials_wrote(c->served_control))) {
        return 1;
    }
    c->served_control[SERVED_BEGUN] = left == STEP_NOT_TAKEN ? 0 : left == STEP_TAKEN_WITH_CVODE ? STEP_FINISH : left;
    return 0;
}

/* In a getter, once its value references are checked: the served values (convert: a cast to the getter's type). */
#define SERVE_VALUES(convert, vr, nvr, value)                   \
    if (served_ready(c_)) {                                     \
        for (size_t i_ = 0; i_ < (nvr); i_++) {                 \
            (value)[i_] = convert(c_->served_values[(vr)[i_]]); \
        }                                                       \
        return FMI(OK);                                         \
    }

/* An FMU state: pythonfmu's, and the state-machine state it was taken in (serialized: one byte in front of
 * pythonfmu's bytes; restoring it restores both). */
typedef struct {
    void *inner;
    int state;
} FmuState;

/* The FmuState to fill: the one the master passes back to be reused, else a new one (NULL: no memory). */
static FmuState *state_to_fill(void *const *FMUstate)
{
    return *FMUstate != NULL ? (FmuState *)*FMUstate : calloc(1, sizeof(FmuState));
}

/* Hand saved back in *FMUstate once pythonfmu's part is in it, or free it if it was new and that failed. */
static FMI(Status) into_state(FMI(Status) status, FmuState *saved, void **FMUstate, int state)
{
    if (status > FMI(Warning)) {
        if (*FMUstate == NULL) {
            free(saved);
        }
        return status;
    }
    saved->state = state;
    *FMUstate = saved;
    return status;
}

/* The live instances, so that a second free of one is refused instead of freeing it twice. */
static Instance *live;
static pthread_mutex_t live_lock = PTHREAD_MUTEX_INITIALIZER;

static void link_live(Instance *instance)
{
    pthread_mutex_lock(&live_lock);
    instance->next = live;
    live = instance;
    pthread_mutex_unlock(&live_lock);
}

/* Remove instance from the list of live instances; 0 if it was not there (freed already). */
static int unlink_live(Instance *instance)
{
    Instance **link;
    pthread_mutex_lock(&live_lock);
    for (link = &live; *link != NULL && *link != instance; link = &(*link)->next) {
    }
    int found = *link != NULL;
    if (found) {
        *link = instance->next;
    }
    pthread_mutex_unlock(&live_lock);
    return found;
}
static char load_error[4096];

static void *symbol(void *library, const char *name)
{
    void *address = dlsym(library, name);
    if (address == NULL && load_error[0] == '\0') {
        snprintf(load_error, sizeof load_error, "%s not found in " BB_INNER ": %s", name, dlerror());
    }
    return address;
}

/* Copy the output of `command` (at most size - 1 bytes) into out; 1 if it exited with status 0. */
static int run_command(const char *command, char *out, size_t size)
{
    FILE *pipe = popen(command, "r");
    size_t n;
    if (pipe == NULL) {
        return 0;
    }
    n = fread(out, 1, size - 1, pipe);
    out[n] = '\0';
    return pclose(pipe) == 0;
}

/* Which Python runs the FMU in a master that has none, in this order:
 *   1. the one it was built with (BB_PYTHON, with BB_LIBPYTHON), if it is still there;
 *   2. else the first python3.X (the minor version pythonfmu's binary was built for), then python3,
 *      on PATH whose version is 3.X, that has a shared libpython and imports numpy and scikit-sundae.
 * Fills python and libpython and returns 1, or writes load_error and returns 0. */
static int find_python(char *python, size_t python_size, char *libpython, size_t libpython_size)
{
    static const char *const names[] = {"python" BB_PYTHON_VERSION, "python3"};
    const char *query = "import os, sys, sysconfig, numpy, sksundae.cvode; "
                        "print('%d.%d' % sys.version_info[:2]); "
                        "print(os.path.join(sysconfig.get_config_var('LIBDIR') or '', "
                        "sysconfig.get_config_var('INSTSONAME') or ''))";
    const char *path = getenv("PATH");
    char directories[4096], command[8192], answer[8192];

    if (BB_LIBPYTHON[0] != '\0' && access(BB_PYTHON, X_OK) == 0 && access(BB_LIBPYTHON, R_OK) == 0) {
        snprintf(python, python_size, "%s", BB_PYTHON);
        snprintf(libpython, libpython_size, "%s", BB_LIBPYTHON);
        return 1;
    }
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        snprintf(directories, sizeof directories, "%s", path != NULL ? path : "/usr/bin:/bin");
        for (char *save = NULL, *directory = strtok_r(directories, ":", &save); directory != NULL;
             directory = strtok_r(NULL, ":", &save)) {
            char *newline;
            snprintf(python, python_size, "%s/%s", directory, names[i]);
            if (access(python, X_OK) != 0 || strchr(python, '\'') != NULL) {
                continue;
            }
            snprintf(command, sizeof command, "'%s' -c \"%s\" 2>/dev/null", python, query);
            if (!run_command(command, answer, sizeof answer) || strncmp(answer, BB_PYTHON_VERSION "\n",
                                                                       strlen(BB_PYTHON_VERSION "\n")) != 0) {
                continue;
            }
            snprintf(libpython, libpython_size, "%.4000s", answer + strlen(BB_PYTHON_VERSION "\n"));
            if ((newline = strchr(libpython, '\n')) != NULL) {
                *newline = '\0';
            }
            if (strstr(libpython, ".so") != NULL && access(libpython, R_OK) == 0) {
                return 1;
            }
        }
    }
    snprintf(load_error, sizeof load_error,
             "this FMU needs Python " BB_PYTHON_VERSION " with a shared libpython, numpy and scikit-sundae: it was "
             "built with " BB_PYTHON ", which is not there (or has no shared libpython), and no python"
             BB_PYTHON_VERSION " or python3 on PATH (%.2048s) has them",
             path != NULL ? path : "unset");
    return 0;
}

/* Start a Python (see find_python) in a process that has none. */
static int start_python(void)
{
    void *library;
    wchar_t *(*decode_locale)(const char *, size_t *);
    void (*set_program_name)(const wchar_t *);
    void (*initialize)(int);
    void *(*save_thread)(void);
    wchar_t *program;
    static char python[4096], libpython[4096];

    if (!find_python(python, sizeof python, libpython, sizeof libpython)) {
        return 0;
    }
    library = dlopen(libpython, RTLD_NOW | RTLD_GLOBAL);
    if (library == NULL) {
        snprintf(load_error, sizeof load_error, "this FMU runs %.1024s, and cannot load its libpython: %.2048s",
                 python, dlerror());
        return 0;
    }
    *(void **)&decode_locale = dlsym(library, "Py_DecodeLocale");
    *(void **)&set_program_name = dlsym(library, "Py_SetProgramName");
    *(void **)&initialize = dlsym(library, "Py_InitializeEx");
    *(void **)&save_thread = dlsym(library, "PyEval_SaveThread");
    if (decode_locale == NULL || set_program_name == NULL || initialize == NULL || save_thread == NULL) {
        snprintf(load_error, sizeof load_error, "%.2048s lacks Py_SetProgramName or Py_InitializeEx", libpython);
        return 0;
    }
    program = decode_locale(python, NULL); /* Python keeps using it: never freed */
    set_program_name(program);
    initialize(0); /* 0: leave the master's signal handlers alone */
    save_thread(); /* release the GIL; pythonfmu takes it for each call */
    return 1;
}

/* Start a Python if the process has none, then load pythonfmu's binary (BB_INNER, beside this one):
 * its handle, or NULL with load_error written. */
static void *open_inner(void)
{
    Dl_info self;
    char directory[4096];
    char path[4096 + 64];
    void *library;

    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized") == NULL && !start_python()) {
        return NULL;
    }
    if (dladdr((void *)&open_inner, &self) == 0 || self.dli_fname == NULL) {
        snprintf(load_error, sizeof load_error, "cannot find the directory of the FMU's binary");
        return NULL;
    }
    snprintf(directory, sizeof directory, "%s", self.dli_fname);
    snprintf(path, sizeof path, "%s/" BB_INNER, dirname(directory));
    library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        snprintf(load_error, sizeof load_error, "cannot load %.2048s: %.1024s", path, dlerror());
        return NULL;
    }
    /* pythonfmu 0.7.0 (and pythonfmu3 0.3, the same code) releases its PyState twice when the process exits with
     * its binary loaded (its static shared_ptr's destructor, then its own destructor function), which corrupts the
     * heap: about one exit in four crashed after a few FMPy runs. Release it once, first: exit handlers run in
     * reverse order, and this one is registered after pythonfmu's (fmu/pythonfmu_workarounds.py: its bugs). */
    *(void **)&release_python_state = dlsym(library, "finalizePythonInterpreter");
    if (release_python_state != NULL) {
        atexit(release_python_state);
    }
    return library;
}

/* Whether the Python pythonfmu is about to use has what the FMU needs: runs BB_HOST_CHECK in it, in a
 * namespace of its own, with the GIL. 1 if it has; else 0 with one line in problem. Once passed, it is
 * not run again: what it imported stays imported. */
static int host_ready(char *problem, size_t size)
{
    typedef void PyObject;
    static int passed; /* read and written with the GIL held */
    int (*ensure)(void);
    void (*release)(int);
    PyObject *(*new_dict)(void);
    PyObject *(*builtins)(void);
    int (*set_item)(PyObject *, const char *, PyObject *);
    PyObject *(*get_item)(PyObject *, const char *);
    PyObject *(*run)(const char *, int, PyObject *, PyObject *, void *);
    const char *(*as_utf8)(PyObject *);
    void (*clear_error)(void);
    void (*decref)(PyObject *);
    PyObject *globals = NULL, *result = NULL, *answer;
    const char *text;
    int gil, ready = 0;

    *(void **)&ensure = dlsym(RTLD_DEFAULT, "PyGILState_Ensure");
    *(void **)&release = dlsym(RTLD_DEFAULT, "PyGILState_Release");
    *(void **)&new_dict = dlsym(RTLD_DEFAULT, "PyDict_New");
    *(void **)&builtins = dlsym(RTLD_DEFAULT, "PyEval_GetBuiltins");
    *(void **)&set_item = dlsym(RTLD_DEFAULT, "PyDict_SetItemString");
    *(void **)&get_item = dlsym(RTLD_DEFAULT, "PyDict_GetItemString");
    *(void **)&run = dlsym(RTLD_DEFAULT, "PyRun_StringFlags");
    *(void **)&as_utf8 = dlsym(RTLD_DEFAULT, "PyUnicode_AsUTF8");
    *(void **)&clear_error = dlsym(RTLD_DEFAULT, "PyErr_Clear");
    *(void **)&decref = dlsym(RTLD_DEFAULT, "Py_DecRef");
    if (ensure == NULL || release == NULL || new_dict == NULL || builtins == NULL || set_item == NULL ||
        get_item == NULL || run == NULL || as_utf8 == NULL || clear_error == NULL || decref == NULL) {
        snprintf(problem, size, "BouncingBall cannot check the Python of this process: its C API is not in the "
                 "process's global scope (PyRun_StringFlags and others not found)");
        return 0;
    }
    gil = ensure();
    if (passed) {
        release(gil);
        return 1;
    }
    globals = new_dict();
    if (globals != NULL && set_item(globals, "__builtins__", builtins()) == 0) {
        result = run(BB_HOST_CHECK, 257 /* Py_file_input */, globals, globals, NULL);
    }
    answer = result != NULL ? get_item(globals, "problem") : NULL; /* borrowed */
    text = answer != NULL ? as_utf8(answer) : NULL;
    if (text == NULL) {
        clear_error();
        snprintf(problem, size, "BouncingBall could not run its check of the Python of this process");
    } else if (text[0] != '\0') {
        snprintf(problem, size, "%s", text);
    } else {
        ready = passed = 1;
    }
    if (result != NULL) {
        decref(result);
    }
    if (globals != NULL) {
        decref(globals);
    }
    release(gil);
    return ready;
}

static pthread_once_t load_once = PTHREAD_ONCE_INIT;

static void load(void)
{
    void *library = open_inner();
    if (library == NULL) {
        return;
    }
#define LOAD(name) *(void **)&inner.name = symbol(library, FMI_STRING(name));
    INNER_FUNCTIONS(LOAD)
}

/* --- instances -------------------------------------------------------------------------------------- */
/* 1 if this process can make an instance: the inner binary is loaded and the host's Python has what the
 * FMU needs; else 0 with the reason (one line for the master's log) in problem. */
static int can_instantiate(char *problem, size_t size)
{
    pthread_once(&load_once, load);
    if (load_error[0] != '\0') {
        snprintf(problem, size, "%s", load_error);
        return 0;
    }
    return host_ready(problem, size);
}

/* A new instance in state INSTANTIATED, without its inner instance yet (see keep); NULL if out of memory. */
static Instance *new_instance(const char *instanceName, FMI(Boolean) loggingOn)
{
    Instance *c = calloc(1, sizeof *c);
    if (c == NULL) {
        return NULL;
    }
    c->name = strdup(instanceName != NULL ? instanceName : "");
    if (c->name == NULL) {
        free(c);
        return NULL;
    }
    c->logging_on = loggingOn;
    c->state = INSTANTIATED;
    return c;
}

/* c, now live, if the inner binary made its instance; else NULL, c freed. */
static Instance *keep(Instance *c)
{
    if (c->inner == NULL) {
        free(c->name);
        free(c);
        return NULL;
    }
    link_live(c);
    return c;
}

static void free_instance(FMI_INSTANCE instance)
{
    Instance *c = (Instance *)instance;
    /* A second call for the same instance is undefined by the standard: do nothing rather than
     * free it twice (its memory, and with it the master's logger, is gone: nothing to log to). */
    if (c == NULL || !unlink_live(c)) {
        return;
    }
    unserve(c);
    c->served_values = NULL;
    c->served_control = NULL;
    if (!c->dead) { /* a dead inner instance has released its objects already */
        inner.FreeInstance(c->inner);
    }
    free(c->name);
    free(c);
}

static FMI(Status) set_logging(FMI_INSTANCE instance, FMI(Boolean) loggingOn)
{
    if (instance == NULL) {
        return FMI(Error);
    }
    ((Instance *)instance)->logging_on = loggingOn; /* the inner binary keeps logging everything to us */
    return FMI(OK);
}

/* --- the status of a call --------------------------------------------------------------------------- */
/* For the logger the inner binary calls: remember the worst status logged during the call (finish() makes
 * a logged error the call's status); 1 if the master is to see the message (warnings and errors always, the
 * rest while logging is on). */
static int note(Instance *c, FMI(Status) status)
{
    if (status > c->worst) {
        c->worst = status;
    }
    return status != FMI(OK) || c->logging_on;
}

static void say(Instance *c, FMI(Status) status, const char *format, ...) __attribute__((format(printf, 3, 4)));

/* Log one line to the master (warnings and errors always, the rest while logging is on). */
static void say(Instance *c, FMI(Status) status, const char *format, ...)
{
    char message[4096];
    va_list arguments;
    if (status == FMI(OK) && !c->logging_on) {
        return;
    }
    va_start(arguments, format);
    vsnprintf(message, sizeof message, format, arguments);
    va_end(arguments);
    tell(c, status, status == FMI(OK) ? "logAll" : "logStatusError", message);
}

/* The status of a forwarded call: what the inner binary returned, or Error where the slave logged an error
 * (the inner binaries cannot return Error themselves). A warning the slave logged (a looser tolerance than
 * rtol, an accuracy warning, SUNDIALS' own) is only logged: it describes something the FMU handled, and
 * masters such as fmusim and OMSimulator stop at any status other than OK. A fatal status ends this
 * instance only: Error, then refused further calls. */
static FMI(Status) finish(Instance *c, FMI(Status) status)
{
    if (status == FMI(Fatal)) {
        c->dead = 1;
        return FMI(Error);
    }
    if (c->worst >= FMI(Error) && status < FMI(Error)) {
        status = FMI(Error);
    }
    return status;
}

/* 1 if the call may run in c's state (and interface); else logs why and returns 0. */
static int allowed(Instance *c, const char *function, unsigned mask)
{
    if (c->dead || c->ended) {
        say(c, FMI(Error), "%s refused: an earlier error ended this instance", function);
        return 0;
    }
    if (!in_mode(c, mask)) {
        say(c, FMI(Error), "%s is not allowed in state %s (%s): nothing was done", function, STATE_NAMES[c->state],
            mode_name(c));
        return 0;
    }
    c->worst = FMI(OK);
    return 1;
}

/* The instance of the call (c_, from the argument `instance`), if the call is allowed in its state;
 * else the call returns an error. */
#define CHECK(function)                                                          \
    Instance *c_ = (Instance *)instance;                                         \
    if (c_ == NULL || !allowed(c_, FMI_STRING(function), ALLOWED_##function)) { \
        return FMI(Error);                                                       \
    }

/* Forward to the inner binary, return the combined status, and move to state `next` if it succeeded
 * (GNU ##__VA_ARGS__: gcc and clang drop the comma for calls without arguments). */
#define CALL_TO(next, function, ...)                                               \
    do {                                                                           \
        unserve(c_);                                                               \
        FMI(Status) status_ = finish(c_, inner.function(c_->inner, ##__VA_ARGS__)); \
        if (status_ <= FMI(Warning)) {                                             \
            c_->state = (next);                                                    \
        }                                                                          \
        return status_;                                                            \
    } while (0)

/* A getter forwarded: nothing it reads changes, what is served stays served. */
#define READ_CALL(function, ...) return finish(c_, inner.function(c_->inner, ##__VA_ARGS__))

#define FORWARD_TO(next, function, ...)         \
    do {                                        \
        CHECK(function)                         \
        CALL_TO(next, function, ##__VA_ARGS__); \
    } while (0)

/* Reset: the slave is made anew (MAKING), in state INSTANTIATED if it succeeded. */
static FMI(Status) reset_instance(FMI_INSTANCE instance)
{
    FMI(Status) status;
    CHECK(Reset)
    MAKING(c_, status = finish(c_, inner.Reset(c_->inner)));
    if (status <= FMI(Warning)) {
        c_->state = INSTANTIATED;
    }
    return status;
}

/* A call that leaves the state as it is. */
#define FORWARD(function, ...) FORWARD_TO(c_->state, function, ##__VA_ARGS__)

/* 1 if every vr[i] is a variable of the given type ('R', 'I', 'B' or 'S'); else logs the first that is not. */
static int of_type(Instance *c, const char *function, const FMI(ValueReference) vr[], size_t nvr, char type)
{
    static const char types[] = BB_VARIABLE_TYPES;
    const char *type_name = TYPE_NAMES[strchr("RIBS", type) - "RIBS"];
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= sizeof types - 1 || types[vr[i]] != type) {
            say(c, FMI(Error), "%s: value reference %u is not a variable of type %s in this FMU: nothing was done",
                function, (unsigned)vr[i], type_name);
            return 0;
        }
    }
    return 1;
}

/* --- FMU state (FmuState): a fresh instance given the state of an initialised one is initialised ------ */
static FMI(Status) get_state_inner(FMI_INSTANCE instance, FMI_STATE_TYPE *FMUstate) { FORWARD(GET_STATE, FMUstate); }

static FMI(Status) size_inner(FMI_INSTANCE instance, FMI_STATE_TYPE FMUstate, size_t *size)
{
    FORWARD(STATE_SIZE, FMUstate, size);
}

static FMI(Status) serialize_inner(FMI_INSTANCE instance, FMI_STATE_TYPE FMUstate, FMI(Byte) bytes[], size_t size)
{
    FORWARD(SERIALIZE_STATE, FMUstate, bytes, size);
}

static FMI(Status) deserialize_inner(FMI_INSTANCE instance, const FMI(Byte) bytes[], size_t size,
                                     FMI_STATE_TYPE *FMUstate)
{
    FORWARD(DESERIALIZE_STATE, bytes, size, FMUstate);
}

FMI(Status) FMI(GET_STATE)(FMI_INSTANCE instance, FMI_STATE_TYPE *FMUstate)
{
    FmuState *saved;
    if (instance == NULL || FMUstate == NULL) {
        return FMI(Error);
    }
    saved = state_to_fill(FMUstate);
    if (saved == NULL) {
        return FMI(Error);
    }
    return into_state(get_state_inner(instance, &saved->inner), saved, FMUstate, ((Instance *)instance)->state);
}

FMI(Status) FMI(SET_STATE)(FMI_INSTANCE instance, FMI_STATE_TYPE FMUstate)
{
    FmuState *saved = (FmuState *)FMUstate;
    if (saved == NULL) {
        return FMI(Error);
    }
    FORWARD_TO(saved->state, SET_STATE, saved->inner);
}

FMI(Status) FMI(FREE_STATE)(FMI_INSTANCE instance, FMI_STATE_TYPE *FMUstate)
{
    Instance *c = (Instance *)instance;
    FmuState *saved;
    FMI(Status) status = FMI(OK);
    if (c == NULL || FMUstate == NULL) {
        return FMI(Error);
    }
    saved = (FmuState *)*FMUstate;
    if (saved == NULL) {
        return FMI(OK); /* freeing nothing is allowed */
    }
    if (!c->dead) {
        c->worst = FMI(OK);
        status = finish(c, inner.FREE_STATE(c->inner, &saved->inner));
    }
    free(saved);
    *FMUstate = NULL;
    return status;
}

FMI(Status) FMI(STATE_SIZE)(FMI_INSTANCE instance, FMI_STATE_TYPE FMUstate, size_t *size)
{
    FmuState *saved = (FmuState *)FMUstate;
    FMI(Status) status;
    if (saved == NULL || size == NULL) {
        return FMI(Error);
    }
    status = size_inner(instance, saved->inner, size);
    if (status <= FMI(Warning)) {
        *size += 1;
    }
    return status;
}

FMI(Status) FMI(SERIALIZE_STATE)(FMI_INSTANCE instance, FMI_STATE_TYPE FMUstate, FMI(Byte) serializedState[],
                                 size_t size)
{
    FmuState *saved = (FmuState *)FMUstate;
    if (saved == NULL || serializedState == NULL || size < 1) {
        return FMI(Error);
    }
    serializedState[0] = (FMI(Byte))saved->state;
    return serialize_inner(instance, saved->inner, serializedState + 1, size - 1);
}

FMI(Status) FMI(DESERIALIZE_STATE)(FMI_INSTANCE instance, const FMI(Byte) serializedState[], size_t size,
                                   FMI_STATE_TYPE *FMUstate)
{
    FmuState *saved;
    if (instance == NULL || FMUstate == NULL) {
        return FMI(Error);
    }
    if (!restorable((Instance *)instance, serializedState == NULL || size < 1 ? -1 : (unsigned char)serializedState[0])) {
        return FMI(Error);
    }
    saved = state_to_fill(FMUstate);
    if (saved == NULL) {
        return FMI(Error);
    }
    return into_state(deserialize_inner(instance, serializedState + 1, size - 1, &saved->inner), saved, FMUstate,
                      (unsigned char)serializedState[0]);
}

#endif
