/* Build variant of BouncingBall (tests/fmus/BouncingBallME has its own). */
#define BALL_IDENTIFIER "BouncingBall"
#define BALL_GUID "{3f9a2c71-8d4e-4b6a-a1c5-0e2b7d9f4a01}"
#define BALL_DESCRIPTION "Bouncing ball with a state event (floor) and a time event (kick)"
#define BALL_FLAGS 0u
