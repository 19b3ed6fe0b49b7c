/* A minimal FMI 2.0 co-simulation master in plain C, with no Python in the process.
 *
 * Usage: fmi2_master DIR MODEL_IDENTIFIER GUID STOP_TIME STEP [t=TOLERANCE] [rVR=VALUE ...] [oVR ...] [iVR ...]
 *   DIR               the unzipped FMU
 *   t=TOLERANCE       pass TOLERANCE to fmi2SetupExperiment (toleranceDefined), as OMSimulator passes 1e-4
 *   rVR=VALUE         set Real VR to VALUE before initialisation
 *   oVR, iVR          Real and Integer outputs printed at every communication point
 * Prints "t out1 out2 ..." per communication point on stdout and the FMU's log on stderr.
 * The exit code is 0, or 10 + the status of the first call that did not return fmi2OK: like fmusim and
 * OMSimulator, it stops at any status other than OK, fmi2Warning included.
 * Built with -DHOST_SUNDIALS and linked to a SUNDIALS library, it is a host that carries its own
 * SUNDIALS (as fmusim or OpenModelica do): its symbols are in the process's global scope.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#ifdef HOST_SUNDIALS
#include <sundials/sundials_version.h>
#endif

#define MAX_VARIABLES 64

static void logger(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    va_list args;
    (void)environment;
    fprintf(stderr, "[%s] status %d, %s: ", name, (int)status, category != NULL ? category : "");
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fprintf(stderr, "\n");
}

static void *function(void *library, const char *name)
{
    void *address = dlsym(library, name);
    if (address == NULL) {
        fprintf(stderr, "missing %s: %s\n", name, dlerror());
        exit(2);
    }
    return address;
}

#define CHECK(call, name)                                             \
    do {                                                              \
        fmi2Status status_ = (call);                                  \
        if (status_ != fmi2OK) {                                      \
            printf("%s returned %d\n", name, (int)status_);           \
            return 10 + (int)status_;                                 \
        }                                                             \
    } while (0)

int main(int argc, char *argv[])
{
    char path[4096], resources[4200];
    fmi2ValueReference set_vr[MAX_VARIABLES], real_vr[MAX_VARIABLES], int_vr[MAX_VARIABLES];
    fmi2Real set_value[MAX_VARIABLES], real_out[MAX_VARIABLES];
    fmi2Integer int_out[MAX_VARIABLES];
    size_t n_set = 0, n_real = 0, n_int = 0;
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

    if (argc < 6) {
        fprintf(stderr, "usage: %s DIR MODEL_IDENTIFIER GUID STOP_TIME STEP [t=TOLERANCE] [rVR=VALUE ...] [oVR ...] [iVR ...]\n",
                argv[0]);
        return 2;
    }
#ifdef HOST_SUNDIALS
    char version[64];
    SUNDIALSGetVersion(version, sizeof version);
    fprintf(stderr, "host SUNDIALS %s\n", version);
#endif
    double stop_time = atof(argv[4]);
    double step = atof(argv[5]), tolerance = 0.0;
    fmi2Boolean tolerance_defined = fmi2False;
    for (int i = 6; i < argc && n_set < MAX_VARIABLES && n_real < MAX_VARIABLES && n_int < MAX_VARIABLES; i++) {
        if (strncmp(argv[i], "t=", 2) == 0) {
            tolerance = atof(argv[i] + 2);
            tolerance_defined = fmi2True;
        } else if (argv[i][0] == 'r') {
            char *equals = strchr(argv[i], '=');
            if (equals == NULL) {
                return 2;
            }
            set_vr[n_set] = (fmi2ValueReference)atoi(argv[i] + 1);
            set_value[n_set++] = atof(equals + 1);
        } else if (argv[i][0] == 'o') {
            real_vr[n_real++] = (fmi2ValueReference)atoi(argv[i] + 1);
        } else if (argv[i][0] == 'i') {
            int_vr[n_int++] = (fmi2ValueReference)atoi(argv[i] + 1);
        }
    }

    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", argv[1], argv[2]);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        fprintf(stderr, "cannot load %s: %s\n", path, dlerror());
        return 3;
    }
    fmi2InstantiateTYPE *instantiate = function(library, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = function(library, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = function(library, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init = function(library, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = function(library, "fmi2SetReal");
    fmi2GetRealTYPE *get_real = function(library, "fmi2GetReal");
    fmi2GetIntegerTYPE *get_integer = function(library, "fmi2GetInteger");
    fmi2DoStepTYPE *do_step = function(library, "fmi2DoStep");
    fmi2TerminateTYPE *terminate = function(library, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = function(library, "fmi2FreeInstance");

    snprintf(resources, sizeof resources, "file://%s/resources", argv[1]);
    fmi2Component c = instantiate("master", fmi2CoSimulation, argv[3], resources, &callbacks, fmi2False, fmi2False);
    if (c == NULL) {
        printf("fmi2Instantiate returned NULL\n");
        return 4;
    }
    if (n_set > 0) {
        CHECK(set_real(c, set_vr, n_set, set_value), "fmi2SetReal");
    }
    CHECK(setup(c, tolerance_defined, tolerance, 0.0, fmi2True, stop_time), "fmi2SetupExperiment");
    CHECK(enter(c), "fmi2EnterInitializationMode");
    CHECK(exit_init(c), "fmi2ExitInitializationMode");

    long n_steps = (long)(stop_time / step + 0.5);
    for (long n = 0; n <= n_steps; n++) {
        double t = n * step;
        if (n > 0) {
            CHECK(do_step(c, (n - 1) * step, t - (n - 1) * step, fmi2True), "fmi2DoStep");
        }
        CHECK(get_real(c, real_vr, n_real, real_out), "fmi2GetReal");
        CHECK(get_integer(c, int_vr, n_int, int_out), "fmi2GetInteger");
        printf("%.17g", t);
        for (size_t i = 0; i < n_real; i++) {
            printf(" %.17g", real_out[i]);
        }
        for (size_t i = 0; i < n_int; i++) {
            printf(" %d", int_out[i]);
        }
        printf("\n");
    }
    CHECK(terminate(c), "fmi2Terminate");
    free_instance(c);
    return 0;
}
