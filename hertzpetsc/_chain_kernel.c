/* The chain's right-hand side (eq. nc) and its variational equations, compiled: one pass over the owned beads for
 * the state and the whole block of tangent columns, called by PETSc's TS without Python in between.
 *
 * The arithmetic is that of hertzpetsc.chain.Chain.rhs_reference, operation for operation (same order, no
 * contraction into fused multiply-adds), so the two agree to the last bit wherever libm's sqrt/pow/expm1/log1p
 * agree with numpy's. Layout: bead-major, dof = 2 (1 + n_tangent) values per bead: x, x', then (y, y') per tangent
 * column. The two ghost rows (the neighbours of the first and last owned beads) are copied from the state on one
 * rank (the periodic wrap) and scattered from the neighbouring ranks on several -- only those rows, not the whole
 * ghosted vector; this file then applies what the ghost rows mean: walls and actuators at the ends, the Bloch twist
 * of the tangents at a periodic cell's seam (hertzpetsc.bloch.TwistedChain); and the gap-lattice offset of the
 * positions and the extra length of one bond (hertzpetsc.compacton_window.WindowChain).
 *
 * Built by `python -m hertzpetsc.kernels` (scripts/hz.sh setup) against Debian's libpetsc; PETSc's headers are not
 * needed: the few functions used are declared below with their C signatures (PetscErrorCode = int, PetscScalar =
 * PetscReal = double in the real build; INSERT_VALUES = 1, SCATTER_FORWARD = 0; PETSC_ERR_SIG = 59).
 *
 * Signals: a TS on this function runs without Python in between, so Python's handlers of SIGINT, SIGTERM and SIGHUP
 * (hertzpetsc.options.guarded_main) would run only after the whole solve. hz_watch_signals puts a handler in front
 * of the process's own (it records the signal in a flag, then calls the handler it replaced), and the right-hand
 * side returns PETSC_ERR_SIG once the flag is set: the TS ends at its next stage, and hertzpetsc.kernels.interrupted
 * lets Python's handler raise (one load of the flag per evaluation).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <string.h>

typedef int PetscErrorCode;
typedef struct _p_TS *TS;
typedef struct _p_Vec *Vec;
typedef PetscErrorCode (*RHSFunction)(TS, double, Vec, Vec, void *);

typedef struct _p_VecScatter *VecScatter;
extern PetscErrorCode VecGetArray(Vec, double **);
extern PetscErrorCode VecGetArrayRead(Vec, const double **);
extern PetscErrorCode VecRestoreArrayRead(Vec, const double **);
extern PetscErrorCode VecScatterBegin(VecScatter, Vec, Vec, int, int);
extern PetscErrorCode VecScatterEnd(VecScatter, Vec, Vec, int, int);
extern PetscErrorCode VecRestoreArray(Vec, double **);
extern PetscErrorCode VecGetArrayWrite(Vec, double **);
extern PetscErrorCode VecRestoreArrayWrite(Vec, double **);
extern PetscErrorCode TSSetRHSFunction(TS, Vec, RHSFunction, void *);
extern double petsc_TotalFlops;

#define INSERT_VALUES 1
#define SCATTER_FORWARD 0
#define PETSC_ERR_SIG 59
#define CHECK(call) do { PetscErrorCode ierr_ = (call); if (ierr_) return ierr_; } while (0)

enum { END_INSIDE = 0, END_FREE = 1, END_WALL = 2, END_ACTUATOR = 3 };

/* Mirrored field by field by hertzpetsc.kernels.KernelContext (ctypes). */
typedef struct {
    int serial;                 /* the whole chain on this rank: ghost rows copied from the state */
    VecScatter ghost_scatter;   /* else: the neighbours' rows from the state into ghost_vec (2 x dof) */
    Vec ghost_vec;
    double *ghost;              /* serial: the ghost rows (2 x dof) */
    int nloc, dof, ntan;        /* owned beads, values per bead, tangent columns */
    int left, right;            /* what this rank's ghost rows are: END_* */
    double left_x, left_v, right_x, right_v;   /* actuator position and velocity at the evaluation time */
    double alpha, delta0, delta0_alpha;        /* Hertz law (eq. vhertz), delta0_alpha = delta0^alpha */
    double delta0_base;         /* sqrt(delta0) for a half-whole alpha, else delta0 (compressed_force) */
    int force_k, force_half;    /* |r|^alpha by products and one sqrt (k products, half: sqrt) or pow: k < 0 */
    int stiff_k, stiff_half;    /* |r|^(alpha - 1) likewise */
    double gamma, eta;          /* damping: on-site, between neighbours */
    const double *inv_mass;     /* 1 / m_n of the owned beads, or NULL for unit masses */
    int twist_left, twist_right;   /* this rank holds the seam's left (right) ghost of a twisted cell */
    int complex_modes;          /* tangents 2p, 2p + 1 are Re, Im of complex mode p */
    double cos_theta, sin_theta;
    double gap;                 /* gap-lattice offset: ghosted position i is x_i + gap i */
    int step_bond;              /* the bond (ghosted numbering) that carries the extra length step, or -1 */
    double step;
    double *bond, *stiff, *dv;  /* work arrays, nloc + 1 each */
    int harmonic_left, harmonic_right;   /* that end is an actuator offset + a cos(omega t + phase) ... */
    double harmonic[2][4];      /* ... with (offset, a, omega, phase): its position and velocity computed here */
    /* dissipation in the contacts (hertzpetsc.dissipation), read only by the build with HZ_CONTACT defined: */
    int contact_clipped;        /* a contact never pulls: f_d <= P */
    double contact_g, contact_g_exp;        /* g(d) = contact_g d^contact_g_exp of its tension f_d = g(d) dv, ... */
    double contact_dg, contact_dg_exp;      /* ... g'(d) = contact_dg d^contact_dg_exp */
    double *contact_dfv;        /* work array (nloc + 1): the bonds' df_d/d(dv) */
} ChainKernel;

/* a^e for a >= 0 as hertzpetsc.hertz.abs_power: whole or half-whole e up to 4 by products and one sqrt. */
static inline double abs_power(double a, double e, int k, int half)
{
    if (k < 0) return pow(a, e);
    double out = half ? sqrt(a) : 1.0;
    for (int i = 0; i < k; i++) out = out * a;
    return out;
}

#ifdef HZ_CONTACT
/* d^e for d > 0 as numpy's d ** e with a scalar e (its exponents 1, -1, 0, 1/2 and 2 by a copy, a division, one,
 * sqrt and a product; pow otherwise). */
static inline double scalar_power(double d, double e)
{
    if (e == 1.0) return d;
    if (e == -1.0) return 1.0 / d;
    if (e == 0.0) return 1.0;
    if (e == 0.5) return sqrt(d);
    if (e == 2.0) return d * d;
    return pow(d, e);
}
#endif

/* min(x, 0) and max(x, 0) that keep a NaN (as numpy's minimum / maximum do). */
static inline double min0(double x) { return x > 0.0 ? 0.0 : x; }
static inline double max0(double x) { return x < 0.0 ? 0.0 : x; }

/* delta0^alpha - (delta0 - r)_+^alpha as hertzpetsc.hertz.compressed_force: x times a sum of positive terms for
 * whole and half-whole alpha, expm1(log1p) otherwise. */
static inline double compressed_force(const ChainKernel *k, double r)
{
    if (k->force_k < 0) {
        double ratio = r / k->delta0;
        ratio = ratio > 1.0 ? 1.0 : ratio;
        return -k->delta0_alpha * expm1(k->alpha * log1p(-ratio));
    }
    if (r >= k->delta0) return k->delta0_alpha;
    double gap = max0(k->delta0 - r);
    double s = k->delta0_base, t = k->force_half ? sqrt(gap) : gap;
    int n = k->force_half ? 2 * k->force_k + 1 : k->force_k;
    double p = 1.0, sp = 1.0;
    for (int i = 1; i < n; i++) {
        sp = sp * s;
        p = p * t + sp;
    }
    return k->force_half ? r * p / (s + t) : r * p;
}

static inline double force(const ChainKernel *k, double r)
{
    if (k->delta0 > 0.0) return compressed_force(k, r);
    return -abs_power(-min0(r), k->alpha, k->force_k, k->force_half);
}

static inline double stiffness(const ChainKernel *k, double r)
{
    if (k->delta0 > 0.0)
        return k->alpha * abs_power(max0(k->delta0 - r), k->alpha - 1.0, k->stiff_k, k->stiff_half);
    return k->alpha * abs_power(-min0(r), k->alpha - 1.0, k->stiff_k, k->stiff_half);
}

#ifdef HZ_CONTACT
/* The contact dissipation of a bond of length r and velocity difference dv (hertzpetsc.dissipation.
 * ContactDissipation.bond_terms, in its operations' order): its tension f_d = g(d) dv, d = delta0 - r, and the
 * derivatives df_d/dr = -g'(d) dv, df_d/d(dv) = g(d), all 0 out of contact (d <= 0); clipped, a contact never pulls:
 * where f_d > P = d^alpha, f_d = P, df_d/dr = -alpha d^(alpha - 1), df_d/d(dv) = 0. */
static inline void contact_terms(const ChainKernel *k, double r, double dv, double *f, double *dfr, double *dfv)
{
    double d = k->delta0 - r;
    *f = *dfr = *dfv = 0.0;
    if (!(d > 0.0)) return;
    double g = k->contact_g * scalar_power(d, k->contact_g_exp);
    *f = g * dv;
    *dfr = -(k->contact_dg * scalar_power(d, k->contact_dg_exp)) * dv;
    *dfv = g;
    if (k->contact_clipped) {
        double P = scalar_power(d, k->alpha);
        if (*f > P) {
            *f = P;
            *dfr = -k->alpha * scalar_power(d, k->alpha - 1.0);
            *dfv = 0.0;
        }
    }
}
#endif

/* The ghost row ``row`` of an end: a wall at rest (all zero), an actuator (its position and velocity, zero
 * tangents). */
static void set_end(const ChainKernel *k, double *row, int kind, double x, double v)
{
    if (kind != END_WALL && kind != END_ACTUATOR) return;
    for (int c = 0; c < k->dof; c++) row[c] = 0.0;
    if (kind == END_ACTUATOR) {
        row[0] = x;
        row[1] = v;
    }
}

/* The Bloch twist of the tangents of a ghost row across the seam: e^{sign i theta} (real tangents: cos theta). */
static void twist(const ChainKernel *k, double *row, double sign)
{
    double c = k->cos_theta, s = k->sin_theta;
    if (!k->complex_modes) {
        for (int j = 2; j < k->dof; j++) row[j] *= c;
        return;
    }
    for (int p = 0; p < k->ntan / 2; p++) {          /* mode p: (u_y, u_y', w_y, w_y') */
        double *m = row + 2 + 4 * p;
        for (int d = 0; d < 2; d++) {
            double u = m[d], w = m[2 + d];
            m[d] = c * u - sign * s * w;
            m[2 + d] = sign * s * u + c * w;
        }
    }
}

/* out (nloc x dof) = f: the owned beads' values x (nloc x dof), and the ghost rows gl, gr (dof each) with their
 * meaning already applied (ends, twist). */
static void evaluate(const ChainKernel *k, const double *gl, const double *x, const double *gr, double *out)
{
    const int n = k->nloc, d = k->dof, ntan = k->ntan;
    const int damped = k->gamma > 0.0 || k->eta > 0.0;
    double *bond = k->bond, *stiff = k->stiff, *dv = k->dv;
#define ROW(i) ((i) == 0 ? gl : (i) == n + 1 ? gr : x + (size_t)((i) - 1) * d)   /* ghosted row i */
#define MASK(i) (((i) == 0 && k->left == END_FREE) || ((i) == n && k->right == END_FREE) ? 0.0 : 1.0)
    for (int i = 0; i <= n; i++) {                    /* bond i joins ghosted rows i and i + 1 */
        double xl = ROW(i)[0], xr = ROW(i + 1)[0];
        if (k->gap != 0.0) {
            xl = xl + k->gap * (double)i;
            xr = xr + k->gap * (double)(i + 1);
        }
        double r = xr - xl, mask = MASK(i);
        if (i == k->step_bond) r = r + k->step;
        bond[i] = force(k, r) * mask;
        if (ntan) stiff[i] = stiffness(k, r) * mask;
#ifdef HZ_CONTACT
        {
            double f, dfr, dfv;
            contact_terms(k, r, ROW(i + 1)[1] - ROW(i)[1], &f, &dfr, &dfv);
            bond[i] = bond[i] + f * mask;
            if (ntan) {
                stiff[i] = stiff[i] + dfr * mask;
                k->contact_dfv[i] = dfv * mask;
            }
        }
#endif
    }
    for (int i = 0; i < n; i++) {
        const double *left = ROW(i), *self = ROW(i + 1), *right = ROW(i + 2);
        double *o = out + (size_t)i * d;
        o[0] = self[1];
        o[1] = bond[i + 1] - bond[i];
        if (ntan) {
            const double sl = stiff[i], sr = stiff[i + 1];
            for (int c = 2; c < d; c += 2) {
                o[c] = self[c + 1];
                o[c + 1] = sr * (right[c] - self[c]) - sl * (self[c] - left[c]);
#ifdef HZ_CONTACT
                {                         /* the contacts' df_d/d(dv) on the tangents' velocity differences */
                    const double wr = k->contact_dfv[i + 1] * (right[c + 1] - self[c + 1]);
                    const double wl = k->contact_dfv[i] * (self[c + 1] - left[c + 1]);
                    o[c + 1] = o[c + 1] + (wr - wl);
                }
#endif
            }
        }
    }
    if (damped) {                  /* -gamma v_n + eta (dv_n - dv_{n-1}) on every velocity column */
        const double gamma = k->gamma, eta = k->eta;
        for (int c = 1; c < d; c += 2) {
            if (eta > 0.0)
                for (int i = 0; i <= n; i++) dv[i] = (ROW(i + 1)[c] - ROW(i)[c]) * MASK(i);
            for (int i = 0; i < n; i++) {
                double f = -gamma * x[(size_t)i * d + c];
                if (eta > 0.0) f = f + eta * (dv[i + 1] - dv[i]);
                out[(size_t)i * d + c] += f;
            }
        }
    }
    if (k->inv_mass)
        for (int i = 0; i < n; i++)
            for (int c = 1; c < d; c += 2) out[(size_t)i * d + c] *= k->inv_mass[i];
#undef ROW
#undef MASK
    petsc_TotalFlops += (double)n * (8.0 + 4.0 * ntan);
}

/* The ghost rows (2 x dof: left, right) of the owned values x: the neighbours' rows (on one rank the periodic wrap,
 * copied; on several, the scatter k->ghost_scatter from X into k->ghost_vec), then the ends and the twist. */
static PetscErrorCode ghost_rows(const ChainKernel *k, Vec X, const double *x, double **g)
{
    const int n = k->nloc, d = k->dof;
    if (k->serial) {
        *g = k->ghost;
        if (k->left == END_INSIDE) memcpy(k->ghost, x + (size_t)(n - 1) * d, sizeof(double) * d);
        if (k->right == END_INSIDE) memcpy(k->ghost + d, x, sizeof(double) * d);
    } else {
        CHECK(VecScatterBegin(k->ghost_scatter, X, k->ghost_vec, INSERT_VALUES, SCATTER_FORWARD));
        CHECK(VecScatterEnd(k->ghost_scatter, X, k->ghost_vec, INSERT_VALUES, SCATTER_FORWARD));
        CHECK(VecGetArray(k->ghost_vec, g));
    }
    set_end(k, *g, k->left, k->left_x, k->left_v);
    set_end(k, *g + d, k->right, k->right_x, k->right_v);
    if (k->twist_left) twist(k, *g, -1.0);
    if (k->twist_right) twist(k, *g + d, 1.0);
    return 0;
}

/* Position and velocity at time t of a harmonic actuator h = (offset, a, omega, phase), in the operations' order of
 * hertzpetsc.model.Harmonic.position and velocity. */
static void harmonic_end(const double *h, double t, double *x, double *v)
{
    const double arg = h[2] * t + h[3];
    *x = h[0] + h[1] * cos(arg);
    *v = -h[1] * h[2] * sin(arg);
}

/* A watched signal that arrived during a solve (0: none); ``armed`` between hz_watch_signals and hz_release_signals;
 * the process's handlers that on_signal stands in front of. */
static volatile sig_atomic_t received = 0, armed = 0;
static const int watched[3] = {SIGINT, SIGTERM, SIGHUP};
static struct sigaction previous[3];

static void on_signal(int sig, siginfo_t *info, void *context)
{
    if (armed) {                  /* during a solve: only the flag; the process's handler runs after the solve */
        received = sig;
        return;
    }
    for (int i = 0; i < 3; i++) {
        if (watched[i] != sig) continue;
        const struct sigaction *p = &previous[i];
        if (p->sa_flags & SA_SIGINFO) p->sa_sigaction(sig, info, context);
        else if (p->sa_handler != SIG_DFL && p->sa_handler != SIG_IGN) p->sa_handler(sig);
    }
}

/* Before a solve: put on_signal in front of the process's handler of each watched signal that is handled (not
 * default, not ignored) and not yet watched (again after Python installed another handler), and arm it: a watched
 * signal then sets the flag that makes hz_chain_rhs fail. Returns 0. */
int hz_watch_signals(void)
{
    received = 0;
    for (int i = 0; i < 3; i++) {
        struct sigaction now, mine;
        if (sigaction(watched[i], NULL, &now)) continue;
        if (now.sa_flags & SA_SIGINFO) {
            if (now.sa_sigaction == on_signal) continue;
        } else if (now.sa_handler == SIG_DFL || now.sa_handler == SIG_IGN) {
            continue;
        }
        previous[i] = now;
        mine = now;
        mine.sa_flags |= SA_SIGINFO;
        mine.sa_sigaction = on_signal;
        sigaction(watched[i], &mine, NULL);
    }
    armed = 1;
    return 0;
}

/* After the solve: disarm, and give a signal that arrived meanwhile to the process's handler (Python's records it
 * for its interpreter). Returns that signal, 0 if none. */
int hz_release_signals(void)
{
    armed = 0;
    int sig = received;
    received = 0;
    if (sig) raise(sig);
    return sig;
}

/* The TS right-hand side: F = f(t, X). t enters only through the actuators' motion: computed here for harmonic
 * actuators, set by the caller (hertzpetsc.kernels.ChainKernel.set_time) for other signals. */
PetscErrorCode hz_chain_rhs(TS ts, double t, Vec X, Vec F, void *ctx)
{
    ChainKernel *k = (ChainKernel *)ctx;
    const double *x;
    double *g, *out;
    (void)ts;
    if (received) return PETSC_ERR_SIG;         /* a watched signal: end the solve (hz_watch_signals) */
    if (k->harmonic_left) harmonic_end(k->harmonic[0], t, &k->left_x, &k->left_v);
    if (k->harmonic_right) harmonic_end(k->harmonic[1], t, &k->right_x, &k->right_v);
    CHECK(VecGetArrayRead(X, &x));
    CHECK(ghost_rows(k, X, x, &g));
    CHECK(VecGetArrayWrite(F, &out));
    evaluate(k, g, x, g + k->dof, out);
    CHECK(VecRestoreArrayWrite(F, &out));
    if (!k->serial) CHECK(VecRestoreArray(k->ghost_vec, &g));
    CHECK(VecRestoreArrayRead(X, &x));
    return 0;
}

/* The digest of the source this library was built from (hertzpetsc.kernels.source_digest). */
const char *hz_kernel_source(void)
{
    return HZ_KERNEL_SOURCE;
}

/* Make hz_chain_rhs the right-hand side of ``ts`` (residual vector r). */
PetscErrorCode hz_install_rhs(TS ts, Vec r, void *ctx)
{
    return TSSetRHSFunction(ts, r, hz_chain_rhs, ctx);
}
