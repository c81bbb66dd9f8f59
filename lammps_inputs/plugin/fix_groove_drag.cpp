/* ----------------------------------------------------------------------
   granchain: fix groove/drag (LAMMPS plugin)

   External per-particle forces for 1D chains of spheres in a V-groove
   (chain along x, spheres roll about y; omega_y > 0 rolls a sphere in +x):

   groove Coulomb friction (keyword "groove s S mu MU g G kt KT [gamma GAMMA] [load N]";
   KT, GAMMA and N may instead name a per-atom property d_NAME of fix property/atom,
   for spheres that differ in size or material)
     slip velocity of the sphere on the groove walls
       u = v_x - s*R*omega_y      (rotation yes)
       u = v_x                    (rotation no)
     Coulomb limit  Fc = mu*(m*g/s + N)  (walls carry a total normal load m*g/s from the
     weight, plus N: e.g. the adhesive pull-off of the two sphere-flat contacts; N = 0
     unless given)
     Cundall-Strack elastic-plastic spring(-dashpot) with per-atom history xi
     (gamma = 0 unless given; the return mapping is that of LAMMPS
     pair granular "tangential linear_history"):
       every time step (post_force):
         xi += u*dt
         F   = -kt*xi - gamma*u
         if |F| > Fc:  F = Fc*sign(F),  xi = -F/kt   (return mapping: the spring alone
                      holds the cap; the dashpot is not stored in the history)
       at setup (step 0 of every run): F = -kt*xi - gamma*u, capped at Fc,
         xi is NOT changed (no spurious history from the setup call)
     f_x += F;  torque_y += -s*R*F  (rotation yes)
     No sign() of a velocity is taken anywhere, so there is no chatter
     around zero slip: a rolling (u = 0) or resting sphere feels F = 0
     as long as its spring is unloaded.
     Rigid limit kt -> inf: F = -Fc sgn(u), torque_y = +R*mu*m*g*sgn(u),
     i.e. the groove terms of Eq. 5.1 of the thesis chapter.

   air drag (keyword "drag T0 T L LEN form as_printed|odd")
     F_d = -m*(v_x/T0 - v_x*v_x/L)     form as_printed (default)
     F_d = -m*(v_x/T0 - v_x*|v_x|/L)   form odd
     f_x += F_d

   global vector (cumulative work done ON the particles, energy units):
     [0] groove friction  sum_steps sum_atoms F*u*dt
     [1] air drag         sum_steps sum_atoms F_d*v_x*dt
     using the (half-step) velocities seen at post_force; setup adds none.
   global scalar = [0] + [1]
   per-atom array (3 columns, f_ID[1..3]):
     [1] xi (distance units)
     [2] cumulative work done ON this atom by the groove friction, sum F*u*dt
     [3] cumulative work done ON this atom by the air drag, sum F_d*v_x*dt
     (so the sum of column [2] (or [3]) over all atoms equals vector [0] (or [1]))
------------------------------------------------------------------------- */

#include "fix_groove_drag.h"

#include "atom.h"
#include "comm.h"
#include "error.h"
#include "memory.h"
#include "update.h"
#include "utils.h"

#include <cmath>
#include <cstring>
#include <string>

using namespace LAMMPS_NS;
using namespace FixConst;

/* ---------------------------------------------------------------------- */

FixGrooveDrag::FixGrooveDrag(LAMMPS *lmp, int narg, char **arg) :
    Fix(lmp, narg, arg), peratom(nullptr)
{
  groove_flag = drag_flag = 0;
  rotation = 1;
  drag_form = DRAG_AS_PRINTED;
  sfac = mu = gravity = kt = gamma = load = t0 = lenL = 0.0;
  kt_index = gamma_index = load_index = -1;
  work_local[0] = work_local[1] = 0.0;
  work_all[0] = work_all[1] = 0.0;

  // ---- parse keywords ----
  // groove s S mu MU g G kt KT [gamma GAMMA] [load N]  (sub-keywords in any order)
  // drag T0 T L LEN [form as_printed|odd]
  // rotation yes|no

  int iarg = 3;
  while (iarg < narg) {
    if (strcmp(arg[iarg], "groove") == 0) {
      if (groove_flag) bad_arg("keyword 'groove' given twice");
      groove_flag = 1;
      int have_s = 0, have_mu = 0, have_g = 0, have_kt = 0, have_gamma = 0, have_load = 0;
      iarg++;
      while (iarg < narg) {
        const char *key = arg[iarg];
        int *have = nullptr;
        double *dest = nullptr;
        bool allow_zero = false;
        if (strcmp(key, "s") == 0) {
          have = &have_s; dest = &sfac;
        } else if (strcmp(key, "mu") == 0) {
          have = &have_mu; dest = &mu; allow_zero = true;
        } else if (strcmp(key, "g") == 0) {
          have = &have_g; dest = &gravity; allow_zero = true;
        } else if (strcmp(key, "kt") == 0) {
          have = &have_kt; dest = &kt;
        } else if (strcmp(key, "gamma") == 0) {
          have = &have_gamma; dest = &gamma; allow_zero = true;
        } else if (strcmp(key, "load") == 0) {
          have = &have_load; dest = &load; allow_zero = true;
        } else break;
        if (*have) bad_arg(fmt::format("groove value '{}' given twice", key));
        if (iarg + 1 >= narg) bad_arg(fmt::format("groove value '{}' needs a number", key));
        if ((dest == &kt || dest == &gamma || dest == &load) &&
            strncmp(arg[iarg + 1], "d_", 2) == 0) {
          // a per-atom value: the custom property d_NAME (fix property/atom)
          std::string &name = (dest == &kt) ? kt_name : (dest == &gamma) ? gamma_name : load_name;
          name = arg[iarg + 1] + 2;
          if (name.empty())
            bad_arg(fmt::format("groove value '{}' needs a property name after d_", key));
        } else {
          *dest = parse_positive(key, arg[iarg + 1], allow_zero);
        }
        *have = 1;
        iarg += 2;
      }
      if (!have_s) bad_arg("keyword 'groove' needs 's S'");
      if (!have_mu) bad_arg("keyword 'groove' needs 'mu MU'");
      if (!have_g) bad_arg("keyword 'groove' needs 'g G'");
      if (!have_kt) bad_arg("keyword 'groove' needs 'kt KT'");
      if (sfac > 1.0)
        bad_arg(fmt::format("value of 's' must be in (0,1] (got {})", sfac));
    } else if (strcmp(arg[iarg], "drag") == 0) {
      if (drag_flag) bad_arg("keyword 'drag' given twice");
      drag_flag = 1;
      int have_t0 = 0, have_l = 0, have_form = 0;
      iarg++;
      while (iarg < narg) {
        const char *key = arg[iarg];
        if (strcmp(key, "T0") == 0 || strcmp(key, "L") == 0) {
          int *have = (key[0] == 'T') ? &have_t0 : &have_l;
          if (*have) bad_arg(fmt::format("drag value '{}' given twice", key));
          if (iarg + 1 >= narg) bad_arg(fmt::format("drag value '{}' needs a number", key));
          double val = parse_positive(key, arg[iarg + 1], false);
          if (key[0] == 'T') t0 = val;
          else lenL = val;
          *have = 1;
          iarg += 2;
        } else if (strcmp(key, "form") == 0) {
          if (have_form) bad_arg("drag value 'form' given twice");
          if (iarg + 1 >= narg) bad_arg("drag value 'form' needs as_printed or odd");
          if (strcmp(arg[iarg + 1], "as_printed") == 0) drag_form = DRAG_AS_PRINTED;
          else if (strcmp(arg[iarg + 1], "odd") == 0) drag_form = DRAG_ODD;
          else
            bad_arg(fmt::format("drag value 'form' must be as_printed or odd (got '{}')",
                                arg[iarg + 1]));
          have_form = 1;
          iarg += 2;
        } else break;
      }
      if (!have_t0) bad_arg("keyword 'drag' needs 'T0 T'");
      if (!have_l) bad_arg("keyword 'drag' needs 'L LEN'");
    } else if (strcmp(arg[iarg], "rotation") == 0) {
      if (iarg + 1 >= narg) bad_arg("keyword 'rotation' needs yes or no");
      if (strcmp(arg[iarg + 1], "yes") == 0) rotation = 1;
      else if (strcmp(arg[iarg + 1], "no") == 0) rotation = 0;
      else bad_arg(fmt::format("keyword 'rotation' must be yes or no (got '{}')", arg[iarg + 1]));
      iarg += 2;
    } else {
      bad_arg(fmt::format("unknown keyword '{}'", arg[iarg]));
    }
  }

  if (!groove_flag && !drag_flag) bad_arg("needs at least one of the keywords 'groove' or 'drag'");

  // ---- fix properties ----

  scalar_flag = 1;
  vector_flag = 1;
  size_vector = 2;
  global_freq = 1;
  extscalar = 1;
  extvector = 1;

  peratom_flag = 1;
  size_peratom_cols = NPERATOM;
  peratom_freq = 1;

  restart_global = 1;
  restart_peratom = 1;
  create_attribute = 1;
  dynamic_group_allow = 1;
  maxexchange = NPERATOM;

  // per-atom history and works: allocate, register for growth/migration/restart, zero

  FixGrooveDrag::grow_arrays(atom->nmax);
  atom->add_callback(Atom::GROW);
  atom->add_callback(Atom::RESTART);
  for (int i = 0; i < atom->nmax; i++)
    for (int k = 0; k < NPERATOM; k++) peratom[i][k] = 0.0;
}

/* ---------------------------------------------------------------------- */

FixGrooveDrag::~FixGrooveDrag()
{
  if (copymode) return;
  atom->delete_callback(id, Atom::GROW);
  atom->delete_callback(id, Atom::RESTART);
  memory->destroy(peratom);
}

/* ---------------------------------------------------------------------- */

void FixGrooveDrag::bad_arg(const std::string &msg)
{
  error->all(FLERR, "Fix groove/drag: " + msg);
}

/* ----------------------------------------------------------------------
   parse a strictly positive (or, with allow_zero, non-negative) number
------------------------------------------------------------------------- */

double FixGrooveDrag::parse_positive(const char *key, const char *val, bool allow_zero)
{
  if (!utils::is_double(val) && !utils::is_integer(val))
    bad_arg(fmt::format("value of '{}' must be a number (got '{}')", key, val));
  double x = utils::numeric(FLERR, val, false, lmp);
  if (!std::isfinite(x)) bad_arg(fmt::format("value of '{}' must be finite (got '{}')", key, val));
  if (allow_zero ? (x < 0.0) : (x <= 0.0))
    bad_arg(fmt::format("value of '{}' must be {} (got '{}')", key, allow_zero ? ">= 0" : "> 0",
                        val));
  return x;
}

/* ---------------------------------------------------------------------- */

int FixGrooveDrag::setmask()
{
  int mask = 0;
  mask |= POST_FORCE;
  return mask;
}

/* ---------------------------------------------------------------------- */

void FixGrooveDrag::init()
{
  if (utils::strmatch(update->integrate_style, "^respa"))
    error->all(FLERR, "Fix groove/drag: run_style respa is not supported");
  if (!atom->rmass_flag && !atom->mass)
    error->all(FLERR, "Fix groove/drag: atoms need a mass (rmass or per-type mass)");
  if (groove_flag && rotation) {
    if (!atom->radius_flag || !atom->omega_flag || !atom->torque_flag)
      error->all(FLERR,
                 "Fix groove/drag: 'rotation yes' needs atom attributes radius, omega, torque "
                 "(atom_style sphere)");
  }
  kt_index = custom_index(kt_name, "kt");
  gamma_index = custom_index(gamma_name, "gamma");
  load_index = custom_index(load_name, "load");
}

/* ----------------------------------------------------------------------
   index of the per-atom double vector d_NAME (fix property/atom), -1 if the value is
   a number
------------------------------------------------------------------------- */

int FixGrooveDrag::custom_index(const std::string &name, const char *key)
{
  if (name.empty()) return -1;
  int flag = -1, cols = -1;
  const int index = atom->find_custom(name.c_str(), flag, cols);
  if (index < 0 || flag != 1 || cols != 0)
    error->all(FLERR,
               "Fix groove/drag: groove value '{}' names d_{}, which is not a per-atom "
               "floating-point vector: define it with fix property/atom d_{} (before this fix)",
               key, name, name);
  return index;
}

/* ----------------------------------------------------------------------
   per-atom kt must be > 0, gamma >= 0 and load >= 0 (finite) on every atom of the group
------------------------------------------------------------------------- */

void FixGrooveDrag::check_peratom()
{
  if (kt_index < 0 && gamma_index < 0 && load_index < 0) return;
  const double *ktv = kt_index >= 0 ? atom->dvector[kt_index] : nullptr;
  const double *gav = gamma_index >= 0 ? atom->dvector[gamma_index] : nullptr;
  const double *ldv = load_index >= 0 ? atom->dvector[load_index] : nullptr;
  const int *mask = atom->mask;
  int bad = 0;
  for (int i = 0; i < atom->nlocal; i++) {
    if (!(mask[i] & groupbit)) continue;
    if (ktv && !(std::isfinite(ktv[i]) && ktv[i] > 0.0)) bad = 1;
    if (gav && !(std::isfinite(gav[i]) && gav[i] >= 0.0)) bad = 1;
    if (ldv && !(std::isfinite(ldv[i]) && ldv[i] >= 0.0)) bad = 1;
  }
  int any = 0;
  MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, world);
  if (any)
    error->all(FLERR, "Fix groove/drag: a per-atom groove value is out of range on some atom "
                      "(kt must be > 0, gamma >= 0, load >= 0, all finite)");
}

/* ----------------------------------------------------------------------
   setup: forces for step 0 of a run, history is not advanced
------------------------------------------------------------------------- */

void FixGrooveDrag::setup(int /*vflag*/)
{
  check_peratom();
  apply(0);
}

/* ----------------------------------------------------------------------
   every step: called after pair forces, before fix nve/sphere's
   final_integrate; x is at t+dt, v and omega are at t+dt/2
------------------------------------------------------------------------- */

void FixGrooveDrag::post_force(int /*vflag*/)
{
  apply(1);
}

/* ----------------------------------------------------------------------
   add groove and drag forces/torques; increment = 1 advances the spring
   history by one time step and accumulates work
------------------------------------------------------------------------- */

void FixGrooveDrag::apply(int increment)
{
  double **v = atom->v;
  double **f = atom->f;
  double **omega = atom->omega;
  double **torque = atom->torque;
  double *radius = atom->radius;
  double *rmass = atom->rmass;
  double *mass = atom->mass;
  int *type = atom->type;
  int *mask = atom->mask;
  const int nlocal = atom->nlocal;
  const double dt = update->dt;
  const int use_rot = groove_flag && rotation;
  // per-atom stick spring and dashpot (d_NAME), or the fix's own values
  const double *ktv = kt_index >= 0 ? atom->dvector[kt_index] : nullptr;
  const double *gav = gamma_index >= 0 ? atom->dvector[gamma_index] : nullptr;
  const double *ldv = load_index >= 0 ? atom->dvector[load_index] : nullptr;

  for (int i = 0; i < nlocal; i++) {
    if (!(mask[i] & groupbit)) continue;

    const double m = rmass ? rmass[i] : mass[type[i]];
    const double vx = v[i][0];

    if (groove_flag) {
      // slip velocity of the sphere's surface on the groove walls
      const double lever = use_rot ? sfac * radius[i] : 0.0;
      const double u = use_rot ? vx - lever * omega[i][1] : vx;

      double &xi = peratom[i][0];
      if (increment) xi += u * dt;

      const double kti = ktv ? ktv[i] : kt;
      const double gai = gav ? gav[i] : gamma;
      double fg = -kti * xi - gai * u;
      const double fc = mu * (m * gravity / sfac + (ldv ? ldv[i] : load));
      if (std::fabs(fg) > fc) {
        fg = std::copysign(fc, fg);    // sign of the trial force, not of a velocity
        // return mapping: the spring alone holds the cap. Unlike LAMMPS's
        // linear_history we do not store the dashpot in the history: with
        // gamma*u >> Fc (fast slides) that would wind up a history which later
        // cancels the friction while the sphere still slides.
        if (increment) xi = -fg / kti;
      }

      f[i][0] += fg;
      if (use_rot) torque[i][1] -= lever * fg;
      if (increment) {
        const double w = fg * u * dt;
        work_local[0] += w;
        peratom[i][1] += w;
      }
    }

    if (drag_flag) {
      const double quad = (drag_form == DRAG_ODD) ? vx * std::fabs(vx) : vx * vx;
      const double fd = -m * (vx / t0 - quad / lenL);
      f[i][0] += fd;
      if (increment) {
        const double w = fd * vx * dt;
        work_local[1] += w;
        peratom[i][2] += w;
      }
    }
  }
}

/* ---------------------------------------------------------------------- */

double FixGrooveDrag::compute_scalar()
{
  MPI_Allreduce(work_local, work_all, 2, MPI_DOUBLE, MPI_SUM, world);
  return work_all[0] + work_all[1];
}

/* ---------------------------------------------------------------------- */

double FixGrooveDrag::compute_vector(int n)
{
  MPI_Allreduce(work_local, work_all, 2, MPI_DOUBLE, MPI_SUM, world);
  return work_all[n];
}

/* ---------------------------------------------------------------------- */

double FixGrooveDrag::memory_usage()
{
  return (double) atom->nmax * NPERATOM * sizeof(double);
}

/* ---------------------------------------------------------------------- */

void FixGrooveDrag::grow_arrays(int nmax)
{
  memory->grow(peratom, nmax, NPERATOM, "groove/drag:peratom");
  array_atom = peratom;
}

/* ---------------------------------------------------------------------- */

void FixGrooveDrag::copy_arrays(int i, int j, int /*delflag*/)
{
  for (int k = 0; k < NPERATOM; k++) peratom[j][k] = peratom[i][k];
}

/* ----------------------------------------------------------------------
   atoms created during a run start with an unloaded spring and no work
------------------------------------------------------------------------- */

void FixGrooveDrag::set_arrays(int i)
{
  for (int k = 0; k < NPERATOM; k++) peratom[i][k] = 0.0;
}

/* ---------------------------------------------------------------------- */

int FixGrooveDrag::pack_exchange(int i, double *buf)
{
  for (int k = 0; k < NPERATOM; k++) buf[k] = peratom[i][k];
  return NPERATOM;
}

/* ---------------------------------------------------------------------- */

int FixGrooveDrag::unpack_exchange(int nlocal, double *buf)
{
  for (int k = 0; k < NPERATOM; k++) peratom[nlocal][k] = buf[k];
  return NPERATOM;
}

/* ----------------------------------------------------------------------
   per-atom restart: [count, xi, groove work, drag work]
------------------------------------------------------------------------- */

int FixGrooveDrag::pack_restart(int i, double *buf)
{
  buf[0] = NPERATOM + 1;    // LAMMPS convention: first value = number of values incl. itself
  for (int k = 0; k < NPERATOM; k++) buf[k + 1] = peratom[i][k];
  return NPERATOM + 1;
}

/* ---------------------------------------------------------------------- */

void FixGrooveDrag::unpack_restart(int nlocal, int nth)
{
  double **extra = atom->extra;

  // skip to the nth fix's values
  int m = 0;
  for (int i = 0; i < nth; i++) m += static_cast<int>(extra[nlocal][m]);
  m++;
  for (int k = 0; k < NPERATOM; k++) peratom[nlocal][k] = extra[nlocal][m + k];
}

/* ---------------------------------------------------------------------- */

int FixGrooveDrag::size_restart(int /*nlocal*/)
{
  return NPERATOM + 1;
}

/* ---------------------------------------------------------------------- */

int FixGrooveDrag::maxsize_restart()
{
  return NPERATOM + 1;
}

/* ----------------------------------------------------------------------
   global restart: the cumulative work (summed over procs)
------------------------------------------------------------------------- */

void FixGrooveDrag::write_restart(FILE *fp)
{
  double list[2];
  MPI_Allreduce(work_local, list, 2, MPI_DOUBLE, MPI_SUM, world);
  if (comm->me == 0) {
    int size = 2 * sizeof(double);
    fwrite(&size, sizeof(int), 1, fp);
    fwrite(list, sizeof(double), 2, fp);
  }
}

/* ---------------------------------------------------------------------- */

void FixGrooveDrag::restart(char *buf)
{
  auto list = reinterpret_cast<double *>(buf);
  // the totals live on proc 0 only, so that the MPI sum stays correct
  if (comm->me == 0) {
    work_local[0] = list[0];
    work_local[1] = list[1];
  } else {
    work_local[0] = work_local[1] = 0.0;
  }
}
