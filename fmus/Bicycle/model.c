/*
 * Bicycle model: the paper's design model (EQUATIONS.md).
 *   lateral : linear bicycle, eq. 1-2, tyre forces 2 mu C alpha per axle;
 *   longitudinal : equivalent wheel, eq. 5, me = m + iy / Rw^2 (iy: all wheels), with
 *                  Fwx = -cx vx|vx| + wind_fx;
 *   side wind wind_fy at lw ahead of the CG;  world kinematics x, y, psi.
 * Integration: classical RK4 with fixed sub-steps of at most H_MAX per
 * communication step, inputs held constant (see README.md for the choice).
 * Low speed: the slip angles divide by max(vx, V_MIN) and the steering term is
 * faded by min(1, vx / V_MIN), so the model never divides by zero and a
 * steered car at standstill does not move sideways.
 */
#include <math.h>
#include <string.h>

#include "model.h"
#include "variable_table.h"

#define H_MAX 1.0e-3   /* s, largest RK4 sub-step */
#define V_MIN 1.0      /* m/s, speed floor of the tyre slip terms */
#define N_STATE 6

static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
};

enum { S_X, S_Y, S_PSI, S_VX, S_VY, S_R };

typedef struct {
    double s[N_STATE];      /* x, y, psi, vx, vy, r */
} BicycleState;

/* Parameters and inputs gathered from values[] once per step. */
typedef struct {
    double m, Iz, Cf, Cr, lf, lr, me, Rw, cx, lw;
    double delta, torque, wind_fx, wind_fy, mu;
} Params;

static Params read_params(const double *v)
{
    Params p;
    p.m = v[VR_m]; p.Iz = v[VR_Iz]; p.Cf = v[VR_Cf]; p.Cr = v[VR_Cr];
    p.lf = v[VR_lf]; p.lr = v[VR_lr]; p.Rw = v[VR_Rw]; p.cx = v[VR_cx]; p.lw = v[VR_lw];
    p.me = p.m + v[VR_iy] / (p.Rw * p.Rw);
    p.delta = v[VR_delta]; p.torque = v[VR_torque];
    p.wind_fx = v[VR_wind_fx]; p.wind_fy = v[VR_wind_fy]; p.mu = v[VR_mu];
    return p;
}

/* State derivative ds = f(s) for held inputs; c, sn = cos, sin of s[S_PSI]. */
static void derivative(const Params *p, const double *s, double c, double sn, double *ds)
{
    double vx = s[S_VX], vy = s[S_VY], r = s[S_R];
    double v_eff = fmax(vx, V_MIN);
    double fade = fmin(1.0, fmax(vx, 0.0) / V_MIN);
    double alpha_f = fade * p->delta - (vy + p->lf * r) / v_eff;
    double alpha_r = -(vy - p->lr * r) / v_eff;
    double fyf = 2.0 * p->mu * p->Cf * alpha_f;
    double fyr = 2.0 * p->mu * p->Cr * alpha_r;
    double fwx = -p->cx * vx * fabs(vx) + p->wind_fx;

    ds[S_X] = vx * c - vy * sn;
    ds[S_Y] = vx * sn + vy * c;
    ds[S_PSI] = r;
    ds[S_VX] = (p->torque / p->Rw + p->m * vy * r + fwx) / p->me;
    ds[S_VY] = (fyf + fyr + p->wind_fy) / p->m - vx * r;
    ds[S_R] = (p->lf * fyf - p->lr * fyr + p->lw * p->wind_fy) / p->Iz;
}

/* cos and sin of psi0 + d from those of psi0. The RK4 stages are a small
   heading increment d away from the sub-step start, so a short Taylor series
   of the rotation by d (error < d^8/40320) replaces three of the four cos/sin
   pairs per sub-step; exact functions for a larger d. Odd/even series keep
   left/right mirror runs bit-identical. */
static void rotate(double c0, double s0, double psi0, double d, double *c, double *sn)
{
    if (fabs(d) > 1e-2) {
        *c = cos(psi0 + d);
        *sn = sin(psi0 + d);
        return;
    }
    double d2 = d * d;
    double cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0));
    double sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0)));
    *c = c0 * cd - s0 * sd;
    *sn = s0 * cd + c0 * sd;
}

static void rk4_step(const Params *p, double *s, double h)
{
    double k1[N_STATE], k2[N_STATE], k3[N_STATE], k4[N_STATE], tmp[N_STATE];
    double psi0 = s[S_PSI], c0 = cos(psi0), s0 = sin(psi0), c, sn;
    int i;
    derivative(p, s, c0, s0, k1);
    for (i = 0; i < N_STATE; ++i) tmp[i] = s[i] + 0.5 * h * k1[i];
    rotate(c0, s0, psi0, 0.5 * h * k1[S_PSI], &c, &sn);
    derivative(p, tmp, c, sn, k2);
    for (i = 0; i < N_STATE; ++i) tmp[i] = s[i] + 0.5 * h * k2[i];
    rotate(c0, s0, psi0, 0.5 * h * k2[S_PSI], &c, &sn);
    derivative(p, tmp, c, sn, k3);
    for (i = 0; i < N_STATE; ++i) tmp[i] = s[i] + h * k3[i];
    rotate(c0, s0, psi0, h * k3[S_PSI], &c, &sn);
    derivative(p, tmp, c, sn, k4);
    for (i = 0; i < N_STATE; ++i)
        s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

/* Outputs from the state; accelerations from the derivative at that state. */
static void write_outputs(double *v, const Params *p, const double *s)
{
    double ds[N_STATE];
    derivative(p, s, cos(s[S_PSI]), sin(s[S_PSI]), ds);
    v[VR_x] = s[S_X]; v[VR_y] = s[S_Y]; v[VR_psi] = s[S_PSI];
    v[VR_vx] = s[S_VX]; v[VR_vy] = s[S_VY]; v[VR_r] = s[S_R];
    v[VR_ax] = ds[S_VX] - s[S_VY] * s[S_R];
    v[VR_ay] = ds[S_VY] + s[S_VX] * s[S_R];
    v[VR_phi] = 0.0;
    v[VR_omega_fl] = v[VR_omega_fr] = v[VR_omega_rl] = v[VR_omega_rr] = s[S_VX] / p->Rw;
}

static ModelStatus initialize(double *values, void *state, double t0, const ModelLogger *log)
{
    BicycleState *st = state;
    Params p = read_params(values);
    (void)t0; (void)log;
    memset(st, 0, sizeof *st);
    st->s[S_X] = values[VR_x0];
    st->s[S_Y] = values[VR_y0];
    st->s[S_PSI] = values[VR_psi0];
    st->s[S_VX] = values[VR_vx0];
    write_outputs(values, &p, st->s);
    return MODEL_OK;
}

static ModelStatus do_step(double *values, void *state, double t, double h, const ModelLogger *log)
{
    BicycleState *st = state;
    Params p = read_params(values);
    long n = (long)ceil(h / H_MAX - 1e-9);
    if (n < 1) n = 1;
    if (n > 10000000L) {
        model_logf(log, LOG_ERROR, "Bicycle: step %g s at t = %g is too long (max 1e4 s)", h, t);
        return MODEL_ERROR;
    }
    for (long i = 0; i < n; ++i) rk4_step(&p, st->s, h / (double)n);
    write_outputs(values, &p, st->s);
    return MODEL_OK;
}

const ModelDefinition MODEL = {
    "Bicycle",
    "{5b1c7e0a-2f3d-4c1e-9a6b-b1c7c1e00001}",
    "Linear bicycle model of Nehaoua & Nouveliere (IV 2012): lateral eq. 1-2 with linear "
    "tyres scaled by mu, equivalent-wheel longitudinal eq. 5 with aero drag and wind",
    VARIABLES,
    sizeof VARIABLES / sizeof VARIABLES[0],
    sizeof(BicycleState),
    0.01,
    NULL,
    initialize,
    do_step,
};
