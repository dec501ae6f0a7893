/* Build variant of BouncingBall: Model Exchange only (no <CoSimulation>).
   model.c and variables.def are symbolic links to ../BouncingBall/. */
#define BALL_IDENTIFIER "BouncingBallME"
#define BALL_GUID "{3f9a2c71-8d4e-4b6a-a1c5-0e2b7d9f4a02}"
#define BALL_DESCRIPTION "Bouncing ball, Model Exchange only"
#define BALL_FLAGS MODEL_FLAG_NO_COSIMULATION
