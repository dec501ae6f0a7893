/* Build variant of the Faulty model: canBeInstantiatedOnlyOncePerProcess="true".
   model.c and variables.def are symbolic links to ../Faulty/. */
#define FAULTY_IDENTIFIER "FaultyOnce"
#define FAULTY_GUID "{6b3c1f0e-2a4d-4c8e-9f1a-5d7e8b9c0a02}"
#define FAULTY_DESCRIPTION "Faulty test FMU that can be instantiated only once per process"
#define FAULTY_FLAGS MODEL_FLAG_ONE_INSTANCE_PER_PROCESS
