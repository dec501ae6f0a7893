/*
 * model.c - Vehicle8DOF: nonlinear 8-DOF vehicle plant (longitudinal, lateral,
 * yaw, roll, four wheel spins) with a combined-slip tyre model (Dugoff-type,
 * or Magic Formula with load sensitivity and relaxation: parameter tyre_model),
 * quasi-static load transfer, aero drag, side wind and torque split.
 *
 * Equations, parameter table and the integration choice: README.md beside
 * this file. In short: fixed internal sub-steps (<= dt_max and inside the
 * explicit stability limit of the regularised tyre damping), a linearly
 * implicit wheel-spin update with a Coulomb brake that can hold a wheel at
 * exactly zero, symplectic Euler for the body, backward Euler for the roll
 * spring and damper.
 */
#include <math.h>
#include <stddef.h>

#include "model.h"
#include "variable_table.h"

static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
};

#define GRAVITY 9.81
#define N_WHEELS 4
/* Explicit-Euler factor dt * lambda allowed for the stiffest body mode (< 1: no overshoot). */
#define STABILITY_FACTOR 0.8
/* Magnitude below which a velocity or roll quantity is set to exactly zero. */
#define SNAP_ZERO 1e-30

/* Private continuous state (plain data, copied by the runtime for FMU state). */
typedef struct {
    double x, y, psi, vx, vy, r, phi, phid;
    double om[N_WHEELS];     /* wheel spin speeds fl, fr, rl, rr */
    double ax, ay;           /* CG accelerations at the last force evaluation */
    double kap[N_WHEELS];    /* Magic Formula: lagged longitudinal slip kappa' */
    double tana[N_WHEELS];   /* Magic Formula: lagged lateral slip tan(alpha') */
} State;

/* Parameters and quantities derived from them, gathered once per call. */
typedef struct {
    double m, iz, iy, rw, cx, lw;   /* iy: one wheel's spin inertia */
    double ms, ix_s, k_roll, c_roll, roll_split, ms_e, h_cg, h_rc, m_uf, m_ur;
    double lf, lr, wb, tf, tr;
    double fz0[N_WHEELS], c_alpha[N_WHEELS], ck, px[N_WHEELS], py[N_WHEELS];
    double drive_share[N_WHEELS], brake_share[N_WHEELS];
    double f_rr, v_eps, dt_max;
    /* Magic Formula tyre (tyre_model = 1) */
    int pacejka;
    double fz_nom[N_WHEELS], ky_ref[N_WHEELS], ky_load, mu_load;
    double pdx, pdy, pcx, pex, pcy, pey, rbx1, rbx2, rby1, rby2;
    double sigma_x, sigma_y, v_relax;
} Par;

/* Inputs held over one step, with the steering trigonometry done once. */
typedef struct {
    double cd, sd, drive, brake, wind_fx, wind_fy, mu;
} In;

/* Tyre forces of one evaluation, in the wheel frame and in body axes. */
typedef struct {
    double fz[N_WHEELS], fx[N_WHEELS], fy[N_WHEELS], kx[N_WHEELS];
    double fx_sum, fy_sum, mz;
    /* Magic Formula: dFx/dkappa' (>= 0), dkappa'_new/d(Rw om_new) and the
       lag's residual (Rw om - vxw) - v_e kappa' of the implicit wheel update */
    double dfx[N_WHEELS], gk[N_WHEELS], e0[N_WHEELS];
} Forces;

static double sprung_mass(const double *v)
{
    return v[VR_m] - v[VR_m_unsprung];
}

static double sprung_cg_height(const double *v)
{
    return (v[VR_m] * v[VR_h_cg] - v[VR_m_unsprung] * v[VR_Rw]) / sprung_mass(v);
}

/* Load shape of the cornering stiffness, K(Fz) proportional to sin(2 atan(x / ky_load)). */
static double ky_shape(double x, double ky_load)
{
    return sin(2.0 * atan(x / ky_load));
}

static void load_par(const double *v, Par *p)
{
    /* iy is the paper's equivalent inertia of all wheels (me = m + iy / Rw^2) */
    p->m = v[VR_m]; p->iz = v[VR_Iz]; p->iy = v[VR_iy] / N_WHEELS; p->rw = v[VR_Rw];
    p->cx = v[VR_cx]; p->lw = v[VR_lw];
    p->lf = v[VR_lf]; p->lr = v[VR_lr]; p->wb = p->lf + p->lr;
    p->tf = v[VR_track_f]; p->tr = v[VR_track_r];
    p->ms = sprung_mass(v); p->ix_s = v[VR_Ix_s]; p->k_roll = v[VR_k_roll];
    p->c_roll = v[VR_c_roll]; p->roll_split = v[VR_roll_split];
    p->h_cg = v[VR_h_cg]; p->h_rc = v[VR_h_rc];
    p->ms_e = p->ms * (sprung_cg_height(v) - p->h_rc);
    p->m_uf = (p->m - p->ms) * p->lr / p->wb;
    p->m_ur = (p->m - p->ms) * p->lf / p->wb;
    p->ck = v[VR_Ck]; p->f_rr = v[VR_f_rr]; p->v_eps = v[VR_v_eps]; p->dt_max = v[VR_dt_max];
    double fz0f = 0.5 * p->m * GRAVITY * p->lr / p->wb;
    double fz0r = 0.5 * p->m * GRAVITY * p->lf / p->wb;
    double ds = v[VR_drive_split], bs = v[VR_brake_split];
    for (int i = 0; i < N_WHEELS; ++i) {
        int front = i < 2, left = (i % 2) == 0;
        p->fz0[i] = front ? fz0f : fz0r;
        p->c_alpha[i] = front ? v[VR_Cf] : v[VR_Cr];
        p->px[i] = front ? p->lf : -p->lr;
        p->py[i] = 0.5 * (left ? 1.0 : -1.0) * (front ? p->tf : p->tr);
        p->drive_share[i] = 0.5 * (front ? ds : 1.0 - ds);
        p->brake_share[i] = 0.5 * (front ? bs : 1.0 - bs);
    }
    p->pacejka = v[VR_tyre_model] == 1.0;
    p->ky_load = v[VR_ky_load]; p->mu_load = v[VR_mu_load];
    p->pdx = v[VR_pDx]; p->pdy = v[VR_pDy];
    p->pcx = v[VR_pCx]; p->pex = v[VR_pEx]; p->pcy = v[VR_pCy]; p->pey = v[VR_pEy];
    p->rbx1 = v[VR_rBx1]; p->rbx2 = v[VR_rBx2]; p->rby1 = v[VR_rBy1]; p->rby2 = v[VR_rBy2];
    p->sigma_x = v[VR_sigma_x]; p->sigma_y = v[VR_sigma_y]; p->v_relax = v[VR_v_relax];
    double shape_nom = ky_shape(1.0, p->ky_load);  /* once, not per wheel: load_par runs every doStep */
    for (int i = 0; i < N_WHEELS; ++i) {
        double nom = i < 2 ? v[VR_Fz_nom_f] : v[VR_Fz_nom_r];
        p->fz_nom[i] = nom > 0.0 ? nom : p->fz0[i];
        /* K(Fz_nom) = Cf or Cr */
        p->ky_ref[i] = p->c_alpha[i] / shape_nom;
    }
}

static void load_in(const double *v, In *in)
{
    in->cd = cos(v[VR_delta]);
    in->sd = sin(v[VR_delta]);
    in->drive = fmax(v[VR_torque], 0.0);
    in->brake = fmax(-v[VR_torque], 0.0);
    in->wind_fx = v[VR_wind_fx];
    in->wind_fy = v[VR_wind_fy];
    in->mu = v[VR_mu];
}

static double clamp(double x, double lo, double hi)
{
    return fmin(fmax(x, lo), hi);
}

/* Quasi-static vertical loads: longitudinal transfer from ax, lateral transfer
   through the roll springs/dampers, the roll centres and the unsprung masses. */
static void wheel_loads(const Par *p, const State *s, double fz[N_WHEELS])
{
    double d_long = 0.5 * p->m * s->ax * p->h_cg / p->wb;
    double m_roll = p->k_roll * s->phi + p->c_roll * s->phid;
    double d_f = (p->roll_split * m_roll + p->ms * s->ay * p->h_rc * p->lr / p->wb
                  + p->m_uf * s->ay * p->rw) / p->tf;
    double d_r = ((1.0 - p->roll_split) * m_roll + p->ms * s->ay * p->h_rc * p->lf / p->wb
                  + p->m_ur * s->ay * p->rw) / p->tr;
    /* Limit each transfer to what the axle (and the car) carries: a lifted wheel
       carries 0 and the total stays m g, so tyre forces never exceed mu m g. */
    d_long = clamp(d_long, -p->fz0[2], p->fz0[0]);
    double base_f = p->fz0[0] - d_long, base_r = p->fz0[2] + d_long;
    d_f = clamp(d_f, -base_f, base_f);
    d_r = clamp(d_r, -base_r, base_r);
    fz[0] = base_f - d_f;
    fz[1] = base_f + d_f;
    fz[2] = base_r - d_r;
    fz[3] = base_r + d_r;
}

/*
 * Dugoff-type combined slip, scaled by mu Fz / Fz0 (similarity): the demand
 * (Ck kappa, -C tan(alpha)) at static load is saturated by
 * lambda = Fz0 / (2 |demand|), so |F| <= mu Fz and the small-slip stiffnesses are
 * mu Ck and mu C at static load. Slip denominators are max(|vxw|, v_eps).
 * Outputs the wheel-frame forces and kx = dFx / d(Rw om) for the implicit update.
 */
static void tyre(const Par *p, int i, double fz, double mu, double vxw, double vyw,
                 double rw_om, double *fx, double *fy, double *kx)
{
    double inv_den = 1.0 / fmax(fabs(vxw), p->v_eps);
    double f0x = p->ck * (rw_om - vxw) * inv_den;
    double f0y = -p->c_alpha[i] * vyw * inv_den;
    double s = sqrt(f0x * f0x + f0y * f0y);
    double half = 0.5 * p->fz0[i];
    double q = 1.0, dfx_df0x = 1.0;
    if (s > half) {
        double lam = half / s;
        double dq_ds = -2.0 * lam * (1.0 - lam) / s;
        q = lam * (2.0 - lam);
        dfx_df0x = q + f0x * f0x / s * dq_ds;
    }
    double scale = mu * fz / p->fz0[i];
    *fx = scale * q * f0x;
    *fy = scale * q * f0y;
    *kx = scale * dfx_df0x * p->ck * inv_den;
}

/* Velocity of wheel i's contact point in the wheel's own axes (the front wheels are steered). */
static void wheel_velocity(const Par *p, const In *in, const State *s, int i,
                           double *vxw, double *vyw)
{
    double vxc = s->vx - s->r * p->py[i];
    double vyc = s->vy + s->r * p->px[i];
    *vxw = vxc;
    *vyw = vyc;
    if (i < 2) {
        *vxw = vxc * in->cd + vyc * in->sd;
        *vyw = -vxc * in->sd + vyc * in->cd;
    }
}

/* Tyre forces at the current state with the wheel spins om[]. */
static void tyre_forces(const Par *p, const In *in, const State *s, Forces *f)
{
    wheel_loads(p, s, f->fz);
    for (int i = 0; i < N_WHEELS; ++i) {
        double vxw, vyw;
        wheel_velocity(p, in, s, i, &vxw, &vyw);
        tyre(p, i, f->fz[i], in->mu, vxw, vyw, p->rw * s->om[i], &f->fx[i], &f->fy[i], &f->kx[i]);
    }
}

/*
 * Magic Formula (Pacejka) tyre at load fz, road friction mu, slip kappa and
 * tan(alpha) (alpha > 0 gives a force to the right). Pure slip:
 *   F0 = D sin(C atan(B s - E (B s - atan(B s)))),  B = K / (C D),
 *   D = mu pD (1 + mu_load dfz) Fz (peak, >= 0.1 mu pD Fz), dfz = Fz / Fz_nom - 1,
 *   Ky = ky_ref sin(2 atan(Fz / (ky_load Fz_nom))) (Ky(Fz_nom) = Cf, Cr),  Kx = Ck Fz / Fz_nom,
 * so mu scales the peak and not the small-slip stiffness. Combined slip by the
 * cosine weights Gx = cos(atan(Bxa alpha)), Bxa = rBx1 cos(atan(rBx2 kappa)),
 * Gy = cos(atan(Byk kappa)), Byk = rBy1 cos(atan(rBy2 alpha)), then held inside
 * the friction ellipse (Fx/Dx)^2 + (Fy/Dy)^2 <= 1. Also returns dFx/dkappa.
 */
static void pacejka(const Par *p, int i, double fz, double mu, double kap, double tana,
                    double *fx, double *fy, double *dfx)
{
    *fx = *fy = *dfx = 0.0;
    if (!(fz > 0.0) || !(mu > 0.0))
        return;
    double x = fz / p->fz_nom[i];
    double peak = mu * fz * fmax(1.0 + p->mu_load * (x - 1.0), 0.1);
    double dx = p->pdx * peak, dy = p->pdy * peak;
    double kx = p->ck * x;
    double ky = p->ky_ref[i] * ky_shape(x, p->ky_load);
    double alpha = atan(tana);

    double bx = kx / (p->pcx * dx), bk = bx * kap;
    double phx = bk - p->pex * (bk - atan(bk));
    double ax_ = p->pcx * atan(phx);
    double fx0 = dx * sin(ax_);
    double dphx = bx * (1.0 - p->pex) + p->pex * bx / (1.0 + bk * bk);
    double dfx0 = dx * p->pcx * cos(ax_) / (1.0 + phx * phx) * dphx;

    double by = ky / (p->pcy * dy), ba = by * alpha;
    double phy = ba - p->pey * (ba - atan(ba));
    double fy0 = dy * sin(p->pcy * atan(phy));

    double zk = p->rbx2 * kap, ra = p->rbx1 * alpha;
    double u = ra * ra / (1.0 + zk * zk);          /* (Bxa alpha)^2 */
    double gx = 1.0 / sqrt(1.0 + u);
    double du = -2.0 * u * zk * p->rbx2 / (1.0 + zk * zk);
    double dgx = -0.5 * gx * gx * gx * du;
    double byk = p->rby1 / sqrt(1.0 + p->rby2 * alpha * p->rby2 * alpha);
    double gy = 1.0 / sqrt(1.0 + byk * kap * byk * kap);

    double fxc = gx * fx0, fyc = gy * fy0;
    double d = gx * dfx0 + dgx * fx0;
    double rho = (fxc / dx) * (fxc / dx) + (fyc / dy) * (fyc / dy);
    if (rho > 1.0) {
        double s = 1.0 / sqrt(rho);
        fxc *= s; fyc *= s; d *= s;
    }
    *fx = fxc;
    *fy = -fyc;
    *dfx = d;
}

/* Relaxation length at wheel speed vxw: sigma (v / v_relax)^2 below v_relax. */
static double relax_length(const Par *p, double sigma, double vxw)
{
    double r = vxw / p->v_relax;
    return r * r < 1.0 ? sigma * r * r : sigma;
}

/*
 * Magic Formula tyre forces at the current state. With dt > 0 the lateral lag
 * sigma d(tan a')/dt = vyw - v_e tan a' (v_e = max(|vxw|, v_eps)) takes one
 * backward-Euler step with the velocities of the sub-step start (for sigma = 0
 * tan a' = vyw / v_e, the quasi-static slip); with dt = 0 the lags are read only.
 * The longitudinal lag is advanced with the wheel spin in pacejka_wheel_update.
 */
static void pacejka_forces(const Par *p, const In *in, State *s, Forces *f, double dt)
{
    wheel_loads(p, s, f->fz);
    for (int i = 0; i < N_WHEELS; ++i) {
        double vxw, vyw;
        wheel_velocity(p, in, s, i, &vxw, &vyw);
        double ve = fmax(fabs(vxw), p->v_eps);
        double sy = relax_length(p, p->sigma_y, vxw);
        if (dt > 0.0) {
            if (sy > 0.0) {
                double a = dt / sy;
                s->tana[i] = (s->tana[i] + a * vyw) / (1.0 + a * ve);
            } else {
                s->tana[i] = vyw / ve;
            }
        }
        double slip_v = p->rw * s->om[i] - vxw;
        double sx = relax_length(p, p->sigma_x, vxw);
        if (sx > 0.0 && dt > 0.0) {
            double a = dt / sx;
            f->gk[i] = a / (1.0 + a * ve);
            f->e0[i] = slip_v - ve * s->kap[i];
        } else {
            if (sx > 0.0) {
                f->gk[i] = 0.0;
            } else {
                s->kap[i] = slip_v / ve;
                f->gk[i] = 1.0 / ve;
            }
            f->e0[i] = 0.0;
        }
        double dfx;
        pacejka(p, i, f->fz[i], in->mu, s->kap[i], s->tana[i], &f->fx[i], &f->fy[i], &dfx);
        f->dfx[i] = fmax(dfx, 0.0);
        f->kx[i] = f->dfx[i] * f->gk[i];
    }
}

/* Sum the wheel forces into body-axis force and yaw moment, with aero and wind. */
static void body_sums(const Par *p, const In *in, const State *s, Forces *f)
{
    double fxb[N_WHEELS], fyb[N_WHEELS];
    for (int i = 0; i < N_WHEELS; ++i) {
        fxb[i] = f->fx[i];
        fyb[i] = f->fy[i];
    }
    for (int i = 0; i < 2; ++i) {
        fxb[i] = f->fx[i] * in->cd - f->fy[i] * in->sd;
        fyb[i] = f->fx[i] * in->sd + f->fy[i] * in->cd;
    }
    /* Pairwise sums (left + right) keep left/right manoeuvres exactly mirrored. */
    f->fx_sum = (fxb[0] + fxb[1]) + (fxb[2] + fxb[3])
                - p->cx * s->vx * fabs(s->vx) + in->wind_fx;
    f->fy_sum = (fyb[0] + fyb[1]) + (fyb[2] + fyb[3]) + in->wind_fy;
    f->mz = p->lf * (fyb[0] + fyb[1]) - p->lr * (fyb[2] + fyb[3])
            + 0.5 * p->tf * (fxb[1] - fxb[0]) + 0.5 * p->tr * (fxb[3] - fxb[2])
            + p->lw * in->wind_fy;
}

/*
 * Linearly implicit wheel update with a Coulomb resisting torque (brake and
 * rolling resistance) that never reverses the spin: it holds the wheel at 0
 * when its capacity over dt exceeds the free spin. Updates f->fx to first order.
 */
static void wheel_update(const Par *p, const In *in, State *s, Forces *f, double dt)
{
    for (int i = 0; i < N_WHEELS; ++i) {
        double den = p->iy + dt * p->rw * p->rw * f->kx[i];
        double drive = in->drive * p->drive_share[i];
        double resist = in->brake * p->brake_share[i] + p->f_rr * f->fz[i] * p->rw;
        double om_free = s->om[i] + dt * (drive - p->rw * f->fx[i]) / den;
        double cap = dt * resist / den;
        double om_new = 0.0;
        if (om_free > cap)
            om_new = om_free - cap;
        else if (om_free < -cap)
            om_new = om_free + cap;
        f->fx[i] += f->kx[i] * p->rw * (om_new - s->om[i]);
        s->om[i] = om_new;
    }
}

/*
 * Magic Formula wheel update: the wheel spin and the longitudinal lag together,
 * linearly implicit. Backward Euler on the lag gives
 * kappa'_new = kappa' + gk (Rw (om_new - om) + e0), with Fx to first order
 * Fx + dFx/dkappa (kappa'_new - kappa'), so the spin update has the form of the
 * Dugoff one with the stiffness dFx/dkappa gk and the predicted force
 * Fx + dFx/dkappa gk e0 (sigma_x = 0: gk = 1 / v_e, e0 = 0, the quasi-static
 * slip). dFx/dkappa is held >= 0: past the peak the force is explicit.
 */
static void pacejka_wheel_update(const Par *p, const In *in, State *s, Forces *f, double dt)
{
    for (int i = 0; i < N_WHEELS; ++i) {
        double den = p->iy + dt * p->rw * p->rw * f->kx[i];
        double drive = in->drive * p->drive_share[i];
        double resist = in->brake * p->brake_share[i] + p->f_rr * f->fz[i] * p->rw;
        double fx_pred = f->fx[i] + f->kx[i] * f->e0[i];
        double om_free = s->om[i] + dt * (drive - p->rw * fx_pred) / den;
        double cap = dt * resist / den;
        double om_new = 0.0;
        if (om_free > cap)
            om_new = om_free - cap;
        else if (om_free < -cap)
            om_new = om_free + cap;
        double dkap = f->gk[i] * (p->rw * (om_new - s->om[i]) + f->e0[i]);
        f->fx[i] += f->dfx[i] * dkap;
        s->kap[i] += dkap;
        s->om[i] = om_new;
    }
}

/* Roll of the sprung mass about the roll axis over dt: the spring and damper
   backward Euler (stable for any k_roll, c_roll, Ix_s), the lateral and gravity
   moments explicit. */
static void roll_update(const Par *p, State *s, double dt)
{
    double moment = p->ms_e * (s->ay * cos(s->phi) + GRAVITY * sin(s->phi))
                    - p->k_roll * s->phi;
    double den = p->ix_s + dt * p->c_roll + dt * dt * p->k_roll;
    s->phid = (p->ix_s * s->phid + dt * moment) / den;
    s->phi += dt * s->phid;
}

/* One internal sub-step of length dt. */
static void sub_step(const Par *p, const In *in, State *s, double dt)
{
    Forces f;
    if (p->pacejka) {
        pacejka_forces(p, in, s, &f, dt);
        pacejka_wheel_update(p, in, s, &f, dt);
    } else {
        tyre_forces(p, in, s, &f);
        wheel_update(p, in, s, &f, dt);
    }
    body_sums(p, in, s, &f);
    s->ax = f.fx_sum / p->m;
    s->ay = f.fy_sum / p->m;
    double vx = s->vx, vy = s->vy;
    s->vx = vx + dt * (s->ax + vy * s->r);
    s->vy = vy + dt * (s->ay - vx * s->r);
    s->r += dt * f.mz / p->iz;
    roll_update(p, s, dt);
    double psi_mid = s->psi + 0.5 * dt * s->r;
    double c = cos(psi_mid), sn = sin(psi_mid);
    s->x += dt * (s->vx * c - s->vy * sn);
    s->y += dt * (s->vx * sn + s->vy * c);
    s->psi += dt * s->r;
}

/* Accelerations at the current state, for the initial outputs and load transfer. */
static void update_accel(const Par *p, const In *in, State *s)
{
    Forces f;
    if (p->pacejka)
        pacejka_forces(p, in, s, &f, 0.0);
    else
        tyre_forces(p, in, s, &f);
    body_sums(p, in, s, &f);
    s->ax = f.fx_sum / p->m;
    s->ay = f.fy_sum / p->m;
}

/* Motions decaying at standstill would reach subnormal numbers, whose
   arithmetic is ~50 times slower; values this small are physically zero. */
static double snap(double x)
{
    return fabs(x) < SNAP_ZERO ? 0.0 : x;
}

static void snap_state(State *s)
{
    s->vx = snap(s->vx); s->vy = snap(s->vy); s->r = snap(s->r);
    s->phi = snap(s->phi); s->phid = snap(s->phid);
    for (int i = 0; i < N_WHEELS; ++i)
        s->om[i] = snap(s->om[i]);
    for (int i = 0; i < N_WHEELS; ++i) {
        s->kap[i] = snap(s->kap[i]);
        s->tana[i] = snap(s->tana[i]);
    }
}

/*
 * Largest sub-step for which the explicit body update stays monotone with
 * the steepest regularised tyre damping (speeds below v_eps), bounding the
 * load-dependent stiffness sum by m g / min(Fz0) times the static-load value.
 */
static double stable_dt(const Par *p, double mu)
{
    double fz0_min = fmin(p->fz0[0], p->fz0[2]);
    double load = mu * p->m * GRAVITY / fz0_min / p->v_eps;
    double c_max = fmax(p->c_alpha[0], p->c_alpha[2]);
    double arm = fmax(p->lf, p->lr), half_t = 0.5 * fmax(p->tf, p->tr);
    double lam_x = load * p->ck / p->m;
    double lam_y = load * c_max / p->m;
    double lam_r = load * (c_max * arm * arm + p->ck * half_t * half_t) / p->iz;
    double lam = fmax(lam_x, fmax(lam_y, lam_r));
    return lam > 0.0 ? STABILITY_FACTOR / lam : p->dt_max;
}

/*
 * The same bound for the Magic Formula tyre, whose small-slip stiffness does
 * not scale with mu: the lateral stiffness of a tyre is at most
 * ky_ref (sin <= 1) and at most ky_ref (2 / ky_load) Fz / Fz_nom (sin(2 atan z) <= 2 z),
 * the longitudinal one Ck Fz / Fz_nom; the Magic Formula's slope is largest
 * at zero slip for the C, E ranges of variables.def. The lags only lower the
 * tyre damping (d tan a' / d vyw <= 1 / v_e), so the bound holds with them.
 */
static double stable_dt_pacejka(const Par *p)
{
    double mg = p->m * GRAVITY;
    double nom_min = fmin(p->fz_nom[0], p->fz_nom[2]);
    double ky_max = fmax(p->ky_ref[0], p->ky_ref[2]);
    double cy_sum = fmin(N_WHEELS * ky_max, ky_max * 2.0 / p->ky_load * mg / nom_min) / p->v_eps;
    double cx_sum = p->ck * mg / nom_min / p->v_eps;
    double arm = fmax(p->lf, p->lr), half_t = 0.5 * fmax(p->tf, p->tr);
    double lam_x = cx_sum / p->m;
    double lam_y = cy_sum / p->m;
    double lam_r = (cy_sum * arm * arm + cx_sum * half_t * half_t) / p->iz;
    double lam = fmax(lam_x, fmax(lam_y, lam_r));
    return lam > 0.0 ? STABILITY_FACTOR / lam : p->dt_max;
}

static void write_outputs(const State *s, double *v)
{
    v[VR_x] = s->x; v[VR_y] = s->y; v[VR_psi] = s->psi;
    v[VR_vx] = s->vx; v[VR_vy] = s->vy; v[VR_r] = s->r;
    v[VR_ax] = s->ax; v[VR_ay] = s->ay; v[VR_phi] = s->phi;
    v[VR_omega_fl] = s->om[0]; v[VR_omega_fr] = s->om[1];
    v[VR_omega_rl] = s->om[2]; v[VR_omega_rr] = s->om[3];
}

static ModelStatus validate(const double *v, const ModelLogger *log)
{
    int bad = 0;
    if (!(v[VR_tyre_model] == 0.0 || v[VR_tyre_model] == 1.0)) {
        model_logf(log, LOG_ERROR, "parameter tyre_model = %g must be 0 (Dugoff) or 1 "
                   "(Magic Formula)", v[VR_tyre_model]);
        ++bad;
    }
    if (!(sprung_mass(v) > 0.0)) {
        model_logf(log, LOG_ERROR, "parameter m_unsprung = %g must be less than m = %g "
                   "(the unsprung mass is part of the vehicle mass)", v[VR_m_unsprung], v[VR_m]);
        return MODEL_ERROR;
    }
    double hs = sprung_cg_height(v);
    if (!(hs > v[VR_h_rc])) {
        model_logf(log, LOG_ERROR, "parameters h_cg = %g, h_rc = %g, ms = %g: sprung-mass CG "
                   "height %g must be above the roll centre h_rc", v[VR_h_cg], v[VR_h_rc],
                   sprung_mass(v), hs);
        ++bad;
    } else if (!(v[VR_k_roll] > sprung_mass(v) * GRAVITY * (hs - v[VR_h_rc]))) {
        model_logf(log, LOG_ERROR, "parameter k_roll = %g must exceed ms g (hs - h_rc) = %g, "
                   "otherwise the body rolls over under its own weight", v[VR_k_roll],
                   sprung_mass(v) * GRAVITY * (hs - v[VR_h_rc]));
        ++bad;
    }
    return bad ? MODEL_ERROR : MODEL_OK;
}

static ModelStatus initialize(double *v, void *state, double t0, const ModelLogger *log)
{
    (void)t0;
    (void)log;
    State *s = (State *)state;
    Par p;
    In in;
    load_par(v, &p);
    load_in(v, &in);
    s->x = v[VR_x0]; s->y = v[VR_y0]; s->psi = v[VR_psi0]; s->vx = v[VR_vx0];
    s->vy = s->r = s->phi = s->phid = s->ax = s->ay = 0.0;
    for (int i = 0; i < N_WHEELS; ++i) {
        s->om[i] = v[VR_vx0] / p.rw;
        s->kap[i] = s->tana[i] = 0.0;
    }
    update_accel(&p, &in, s);
    write_outputs(s, v);
    return MODEL_OK;
}

static ModelStatus do_step(double *v, void *state, double t, double h, const ModelLogger *log)
{
    State *s = (State *)state;
    Par p;
    In in;
    if (!(h > 0.0)) {
        model_logf(log, LOG_ERROR, "Vehicle8DOF: communication step h = %g at t = %g must be > 0",
                   h, t);
        return MODEL_ERROR;
    }
    load_par(v, &p);
    load_in(v, &in);
    double dt_lim = fmin(p.dt_max, p.pacejka ? stable_dt_pacejka(&p) : stable_dt(&p, in.mu));
    double n_sub = ceil(h / dt_lim * (1.0 - 1e-12));
    double dt = h / n_sub;
    for (long k = 0; k < (long)n_sub; ++k)
        sub_step(&p, &in, s, dt);
    snap_state(s);
    /* ax, ay out are those applied in the last sub-step: re-evaluating them at
       the end state would show the stiff slip's one-sub-step lag instead. */
    write_outputs(s, v);
    return MODEL_OK;
}

const ModelDefinition MODEL = {
    "Vehicle8DOF",
    "{6b1f2f4e-8d0a-4c55-9a0e-8d0f2c6e8a01}",
    "Nonlinear 8-DOF vehicle: longitudinal, lateral, yaw, roll, four wheel spins, "
    "combined-slip Dugoff or Magic Formula tyres, quasi-static load transfer",
    VARIABLES,
    VR_COUNT,
    sizeof(State),
    0.01,
    validate,
    initialize,
    do_step,
};
