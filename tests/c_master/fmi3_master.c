/* A minimal FMI 3.0 co-simulation master in plain C, with no Python in the process.
 *
 * Usage: fmi3_master DIR MODEL_IDENTIFIER TOKEN STOP_TIME STEP [e] [t=TOLERANCE] [rVR=VALUE ...] [oVR ...] [iVR ...]
 *   DIR               the unzipped FMU
 *   e                 allow early return and use event mode (a line is printed at each early return too)
 *   t=TOLERANCE       pass TOLERANCE to fmi3EnterInitializationMode (toleranceDefined)
 *   rVR=VALUE         set Float64 VR to VALUE before initialisation
 *   oVR, iVR          Float64 and Int32 outputs printed at every communication point
 * Prints "t out1 out2 ..." per communication point on stdout and the FMU's log on stderr; it also
 * takes, serializes, restores and frees an FMU state halfway. The exit code is 0, or 10 + the status
 * of the first call that did not return fmi3OK: like fmusim and OMSimulator, it stops at any status
 * other than OK, fmi3Warning included.
 */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define MAX_VARIABLES 64

static void logger(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category, fmi3String message)
{
    (void)environment;
    fprintf(stderr, "status %d, %s: %s\n", (int)status, category != NULL ? category : "", message);
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

#define CHECK(call, name)                                   \
    do {                                                    \
        fmi3Status status_ = (call);                        \
        if (status_ != fmi3OK) {                            \
            printf("%s returned %d\n", name, (int)status_); \
            return 10 + (int)status_;                       \
        }                                                   \
    } while (0)

#define LOAD(name) fmi3##name##TYPE *name = function(library, "fmi3" #name)

int main(int argc, char *argv[])
{
    char path[4096], resources[4200];
    fmi3ValueReference set_vr[MAX_VARIABLES], real_vr[MAX_VARIABLES], int_vr[MAX_VARIABLES];
    fmi3Float64 set_value[MAX_VARIABLES], real_out[MAX_VARIABLES];
    fmi3Int32 int_out[MAX_VARIABLES];
    size_t n_set = 0, n_real = 0, n_int = 0;
    int early = 0;

    if (argc < 6) {
        fprintf(stderr, "usage: %s DIR MODEL_IDENTIFIER TOKEN STOP_TIME STEP [e] [t=TOLERANCE] [rVR=VALUE ...] [oVR ...] [iVR ...]\n",
                argv[0]);
        return 2;
    }
    double stop_time = atof(argv[4]);
    double step = atof(argv[5]), tolerance = 0.0;
    fmi3Boolean tolerance_defined = fmi3False;
    for (int i = 6; i < argc && n_set < MAX_VARIABLES && n_real < MAX_VARIABLES && n_int < MAX_VARIABLES; i++) {
        if (strcmp(argv[i], "e") == 0) {
            early = 1;
        } else if (strncmp(argv[i], "t=", 2) == 0) {
            tolerance = atof(argv[i] + 2);
            tolerance_defined = fmi3True;
        } else if (argv[i][0] == 'r') {
            char *equals = strchr(argv[i], '=');
            if (equals == NULL) {
                return 2;
            }
            set_vr[n_set] = (fmi3ValueReference)atoi(argv[i] + 1);
            set_value[n_set++] = atof(equals + 1);
        } else if (argv[i][0] == 'o') {
            real_vr[n_real++] = (fmi3ValueReference)atoi(argv[i] + 1);
        } else if (argv[i][0] == 'i') {
            int_vr[n_int++] = (fmi3ValueReference)atoi(argv[i] + 1);
        }
    }

    snprintf(path, sizeof path, "%s/binaries/x86_64-linux/%s.so", argv[1], argv[2]);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        fprintf(stderr, "cannot load %s: %s\n", path, dlerror());
        return 3;
    }
    LOAD(InstantiateCoSimulation);
    LOAD(EnterInitializationMode);
    LOAD(ExitInitializationMode);
    LOAD(EnterEventMode);
    LOAD(UpdateDiscreteStates);
    LOAD(EnterStepMode);
    LOAD(SetFloat64);
    LOAD(GetFloat64);
    LOAD(GetInt32);
    LOAD(DoStep);
    LOAD(GetFMUState);
    LOAD(SetFMUState);
    LOAD(FreeFMUState);
    LOAD(SerializedFMUStateSize);
    LOAD(SerializeFMUState);
    LOAD(DeserializeFMUState);
    LOAD(Terminate);
    LOAD(FreeInstance);

    snprintf(resources, sizeof resources, "%s/resources/", argv[1]);
    fmi3Instance c = InstantiateCoSimulation("master", argv[3], resources, fmi3False, fmi3False, early, early, NULL, 0,
                                             NULL, logger, NULL);
    if (c == NULL) {
        printf("fmi3InstantiateCoSimulation returned NULL\n");
        return 4;
    }
    if (n_set > 0) {
        CHECK(SetFloat64(c, set_vr, n_set, set_value, n_set), "fmi3SetFloat64");
    }
    CHECK(EnterInitializationMode(c, tolerance_defined, tolerance, 0.0, fmi3True, stop_time), "fmi3EnterInitializationMode");
    CHECK(ExitInitializationMode(c), "fmi3ExitInitializationMode");
    fmi3Boolean update, terminate, nominals, values, defined, needed, returned;
    fmi3Float64 next_time, reached;
    if (early) {
        CHECK(UpdateDiscreteStates(c, &update, &terminate, &nominals, &values, &defined, &next_time),
              "fmi3UpdateDiscreteStates");
        CHECK(EnterStepMode(c), "fmi3EnterStepMode");
    }

    long n_steps = (long)(stop_time / step + 0.5), n = 0;
    double t = 0.0;
    int state_done = 0;
    for (;;) {
        CHECK(GetFloat64(c, real_vr, n_real, real_out, n_real), "fmi3GetFloat64");
        CHECK(GetInt32(c, int_vr, n_int, int_out, n_int), "fmi3GetInt32");
        printf("%.17g", t);
        for (size_t i = 0; i < n_real; i++) {
            printf(" %.17g", real_out[i]);
        }
        for (size_t i = 0; i < n_int; i++) {
            printf(" %d", int_out[i]);
        }
        printf("\n");
        if (n >= n_steps) {
            break;
        }
        if (!state_done && 2 * n >= n_steps) { /* a state round trip halfway: restore what was just taken */
            fmi3FMUState state = NULL, copy = NULL;
            size_t size;
            CHECK(GetFMUState(c, &state), "fmi3GetFMUState");
            CHECK(SerializedFMUStateSize(c, state, &size), "fmi3SerializedFMUStateSize");
            fmi3Byte *bytes = malloc(size);
            CHECK(SerializeFMUState(c, state, bytes, size), "fmi3SerializeFMUState");
            CHECK(DeserializeFMUState(c, bytes, size, &copy), "fmi3DeserializeFMUState");
            CHECK(SetFMUState(c, copy), "fmi3SetFMUState");
            CHECK(FreeFMUState(c, &copy), "fmi3FreeFMUState");
            CHECK(FreeFMUState(c, &state), "fmi3FreeFMUState");
            free(bytes);
            state_done = 1;
        }
        double end = (n + 1) * step;
        CHECK(DoStep(c, t, end - t, fmi3True, &needed, &terminate, &returned, &reached), "fmi3DoStep");
        if (returned) {
            t = reached;
            if (needed) {
                CHECK(EnterEventMode(c), "fmi3EnterEventMode");
                CHECK(UpdateDiscreteStates(c, &update, &terminate, &nominals, &values, &defined, &next_time),
                      "fmi3UpdateDiscreteStates");
                CHECK(EnterStepMode(c), "fmi3EnterStepMode");
            }
        } else {
            t = end;
            n++;
        }
    }
    CHECK(Terminate(c), "fmi3Terminate");
    FreeInstance(c);
    return 0;
}
