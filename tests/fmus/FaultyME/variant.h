/* Build variant of the Faulty model: Model Exchange only (no <CoSimulation>),
   the fault fired at the time event fault_time (see model.c).
   model.c and variables.def are symbolic links to ../Faulty/. */
#define FAULTY_IDENTIFIER "FaultyME"
#define FAULTY_GUID "{6b3c1f0e-2a4d-4c8e-9f1a-5d7e8b9c0a03}"
#define FAULTY_DESCRIPTION "Faulty test FMU as Model Exchange: the fault fires at the time event fault_time"
#define FAULTY_FLAGS MODEL_FLAG_NO_COSIMULATION
#define FAULTY_MODEL_EXCHANGE 1
