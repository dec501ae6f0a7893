/* Build variant of the Faulty model (tests/fmus/FaultyOnce has its own). */
#define FAULTY_IDENTIFIER "Faulty"
#define FAULTY_GUID "{6b3c1f0e-2a4d-4c8e-9f1a-5d7e8b9c0a01}"
#define FAULTY_DESCRIPTION "Test FMU that fails on purpose (fault_mode) at fault_time"
#define FAULTY_FLAGS 0u
