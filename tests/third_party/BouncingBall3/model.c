/* BouncingBall3: the bouncing ball (physics: shared/ball.h) as an FMI 3.0 FMU. Its state event
 * is the event indicator variable `ground` (the height; 1 once the ball rests). Co-Simulation
 * steps with the exact solution; with Event Mode it leaves each impact to the importer.
 */
#include "plumbing.h"
#include "shared/ball.h"

struct ModelData {
    double time;
    Ball ball;
    double der_h, der_v, ground;
};

const char *const MODEL_GUID = "{8c4e2a90-3f1b-4d6e-9a7c-5b2d1e0f3a01}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 2;
const size_t NUMBER_OF_EVENT_INDICATORS = 1;

const Variable VARIABLES[] = {
    VARIABLE(0, time, Float64Type, Calculated),
    VARIABLE(1, ball.h, Float64Type, Fixed),
    VARIABLE(2, der_h, Float64Type, Calculated),
    VARIABLE(3, ball.v, Float64Type, Fixed),
    VARIABLE(4, der_v, Float64Type, Calculated),
    VARIABLE(5, ball.g, Float64Type, Fixed),
    VARIABLE(6, ball.e, Float64Type, Tunable),
    VARIABLE(7, ball.v_min, Float64Type, Fixed),
    VARIABLE(8, ball.bounces, Int32Type, Calculated),
    VARIABLE(9, ground, Float64Type, Calculated),
};
const size_t NUMBER_OF_VARIABLES = sizeof(VARIABLES) / sizeof(VARIABLES[0]);

#define M(v) (comp->data->v)

Status setStartValues(ModelInstance *comp) {
    ballStart(&M(ball));
    return OK;
}

Status initialize(ModelInstance *comp) {
    ballInitialize(&M(ball));
    return OK;
}

Status calculateValues(ModelInstance *comp) {
    if (!(M(ball).e >= 0 && M(ball).e <= 1)) {
        logError(comp, "e = %g is not a coefficient of restitution (0 <= e <= 1)", M(ball).e);
        return Error;
    }
    M(time) = comp->time;
    M(der_h) = M(ball).v;
    M(der_v) = ballAcceleration(&M(ball));
    M(ground) = ballIndicator(&M(ball));
    return OK;
}

void getContinuousStates(ModelInstance *comp, double x[]) {
    x[0] = M(ball).h;
    x[1] = M(ball).v;
}

void setContinuousStates(ModelInstance *comp, const double x[]) {
    M(ball).h = x[0];
    M(ball).v = x[1];
}

void getDerivatives(ModelInstance *comp, double dx[]) {
    dx[0] = M(ball).v;
    dx[1] = ballAcceleration(&M(ball));
}

void getEventIndicators(ModelInstance *comp, double z[]) { z[0] = ballIndicator(&M(ball)); }

void eventUpdate(ModelInstance *comp) {
    comp->nextEventTimeDefined = false;
    comp->valuesOfContinuousStatesChanged = ballBounce(&M(ball));
}

bool advance(ModelInstance *comp, double t_stop) {
    double dt = t_stop - comp->time;
    bool impact = ballFly(&M(ball), &dt);
    comp->time = impact ? comp->time + dt : t_stop;
    return impact;
}
