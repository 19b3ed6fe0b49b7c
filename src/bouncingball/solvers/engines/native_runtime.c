/* What numba's runtime gives the code it compiles, for the native engine's library (native_build.py), without numba.

   The engine's code, compiled by numba, calls: NRT's allocation of arrays (a MemInfo header, then its data, in
   numba's layout: numba's code reads the header's fields itself), numba's frexp, ldexp and nextafter helpers, and,
   only where its code raised, the error path of a cfunc's wrapper (take the GIL, build the exception, report it).
   Here that path keeps only the count of exceptions (bb_exceptions) and calls no Python: the entry point then returns
   0, which its callers read as "raised" (entry_contract.py). tests/test_native_engine.py checks the MemInfo layout
   against numba's. Every name here is local to the library but bb_exceptions (the link's version script). */
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>

_Atomic long bb_exceptions = 0;

typedef void (*dtor_function)(void *data, size_t size, void *info);
typedef struct {
    _Atomic size_t refct;
    dtor_function dtor;
    void *dtor_info;
    void *data;
    size_t size;
    void *external_allocator;
} MemInfo;

void *NRT_Allocate(size_t size) { return malloc(size); }
void NRT_Free(void *data) { free(data); }

static MemInfo *header(void *base, void *data, size_t size, dtor_function dtor, void *info) {
    MemInfo *meminfo = base;
    meminfo->refct = 1;
    meminfo->dtor = dtor;
    meminfo->dtor_info = info;
    meminfo->data = data;
    meminfo->size = size;
    meminfo->external_allocator = NULL;
    return meminfo;
}

/* The header and its data in one block, freed with the header. */
MemInfo *NRT_MemInfo_alloc_aligned(size_t size, unsigned align) {
    char *base = malloc(sizeof(MemInfo) + size + 2 * (size_t)align);
    if (!base) return NULL;
    uintptr_t data = (uintptr_t)(base + sizeof(MemInfo));
    uintptr_t off = align ? data % align : 0;
    return header(base, (void *)(data + (off ? align - off : 0)), size, NULL, NULL);
}
MemInfo *NRT_MemInfo_alloc(size_t size) { return NRT_MemInfo_alloc_aligned(size, 0); }
MemInfo *NRT_MemInfo_alloc_safe_aligned(size_t size, unsigned align) { return NRT_MemInfo_alloc_aligned(size, align); }

/* Data of its own (numba's lists, ...), freed by the destructor numba gives, then by the runtime. */
static void free_varsize(void *data, size_t size, void *info) {
    if (info) ((void (*)(void *))info)(data);
    free(data);
}
MemInfo *NRT_MemInfo_new_varsize_dtor(size_t size, dtor_function dtor) {
    void *data = malloc(size);
    MemInfo *meminfo = data ? malloc(sizeof(MemInfo)) : NULL;
    if (!meminfo) {
        free(data);
        return NULL;
    }
    return header(meminfo, data, size, free_varsize, (void *)dtor);
}

/* numba's code calls it when a MemInfo's count drops to 0. */
void NRT_MemInfo_call_dtor(MemInfo *meminfo) {
    if (meminfo->dtor) meminfo->dtor(meminfo->data, meminfo->size, meminfo->dtor_info);
    free(meminfo);
}

/* numba's helpers (its _helperlib.c's contract: an exponent of 0 where frexp's is not defined). */
double numba_frexp(double x, int *exponent) {
    if (!isfinite(x) || x == 0.0) {
        *exponent = 0;
        return x;
    }
    return frexp(x, exponent);
}
double numba_ldexp(double x, int exponent) { return (isfinite(x) && x != 0.0 && exponent) ? ldexp(x, exponent) : x; }
double numba_nextafter(double a, double b) { return nextafter(a, b); }

/* The error path: counted, nothing built, nothing raised into Python. */
void numba_gil_ensure(int *state) {
    atomic_fetch_add(&bb_exceptions, 1);
    *state = 0;
}
void numba_gil_release(int *state) { (void)state; }
void *numba_unpickle(const char *data, int size, const char *hashed) { return NULL; }
void *numba_runtime_build_excinfo_struct(void *a, void *b) { return NULL; }
void numba_do_raise(void *excinfo) {}
void PyErr_Clear(void) {}
void PyErr_SetNone(void *type) {}
void PyErr_SetString(void *type, const char *message) {}
void PyErr_WriteUnraisable(void *object) {}
void *PyUnicode_FromString(const char *text) { return NULL; }
void *PyUnicode_FromKindAndData(int kind, const void *buffer, intptr_t size) { return NULL; }
void *PyBytes_FromStringAndSize(const char *bytes, intptr_t size) { return NULL; }
void *PyTuple_Pack(intptr_t size, ...) { return NULL; }
intptr_t PyObject_Hash(void *object) { return -1; }
void Py_DecRef(void *object) {}
void *PyExc_RuntimeError, *PyExc_StopIteration, *PyExc_SystemError;
