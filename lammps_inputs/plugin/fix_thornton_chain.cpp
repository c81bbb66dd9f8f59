/* ----------------------------------------------------------------------
   granchain: fix thornton/chain (LAMMPS plugin)

   Thornton (1997, J. Appl. Mech. 64, 383) elastic-perfectly plastic
   normal contact at the neighbour contacts of 1D sphere chains and at an
   end wall, added to the Hertz force that pair granular (hertz/material)
   and fix wall/gran already apply: this fix adds F_Thornton - F_Hertz.

   fix ID group thornton/chain chain N estar d_ES yield d_PY [wall X]

   Chains: atom ids b*N+1 ... b*N+N form chain b, in chain order (the
   contact i,i+1 of a chain is between atoms of ids t and t+1). The end
   wall is the plane x = X after each chain's last atom (the plane of
   fix wall/gran xplane NULL X). Per contact, with E* and p_y from the
   per-atom vectors d_ES, d_PY of the contact's left atom (the wall's:
   the last atom's) and R* from the radii (the wall's: R_n):
     K = 4/3 E* sqrt(R*), delta_y = R* (pi p_y / (2 E*))^2,
     F_y = K delta_y^1.5, S = pi p_y R*
   the largest overlap dm = max(stored, delta) gives
     dm <= delta_y:  F = K delta^1.5                       (Hertz)
     else:           F_max = F_y + S (dm - delta_y),
                     c = 3 F_max / (4 E* sqrt(R* dm)),
                     F = F_max (1 - (dm - delta)/c)^1.5     (0 below delta_p)
   and the fix adds F - K delta^1.5 (while delta > 0). Every step
   (post_force) the stored largest overlap is raised to delta and the
   energy its rise dissipates (the loading curve's work less the rise of
   the elastic energy at the maximum, 3 F_max^2 / (10 E* a_max)) is booked
   as (negative) work; setup applies the force and raises nothing.

   Per-atom array (f_ID[1..4]), each for the atom's right contact (the
   wall's on a chain's last atom):
     [1] largest overlap (distance units)
     [2] cumulative work of the plastic loading on the particles (energy)
     [3] elastic energy beyond Hertz's at the last force call (energy)
     [4] x force of the wall correction on this atom (force; 0 elsewhere)
   Global scalar: the sum of [2] over all atoms.
------------------------------------------------------------------------- */

#include "fix_thornton_chain.h"

#include "atom.h"
#include "comm.h"
#include "domain.h"
#include "error.h"
#include "memory.h"
#include "update.h"
#include "utils.h"

#include <cmath>
#include <cstring>
#include <string>

using namespace LAMMPS_NS;
using namespace FixConst;

namespace {
constexpr double PI = 3.14159265358979323846;

// the law's constants of one contact
struct Law {
  double es, rs, K, dy, Fy, S;
  Law(double es_, double py, double rs_) : es(es_), rs(rs_)
  {
    K = 4.0 / 3.0 * es * std::sqrt(rs);
    const double q = PI * py / (2.0 * es);
    dy = rs * q * q;
    Fy = K * dy * std::sqrt(dy);
    S = PI * py * rs;
  }
  double hertz(double d) const { return d > 0.0 ? K * d * std::sqrt(d) : 0.0; }
  double hertz_energy(double d) const { return d > 0.0 ? 0.4 * K * d * d * std::sqrt(d) : 0.0; }
  double loading(double dm) const { return Fy + S * (dm - dy); }
  // the unloading curve's span c = delta_max - delta_p at dm > dy
  double span(double Fm, double dm) const { return 0.75 * Fm / (es * std::sqrt(rs * dm)); }
  double force(double d, double dm) const
  {
    if (dm <= dy) return hertz(d);
    const double Fm = loading(dm);
    const double x = 1.0 - (dm - d) / span(Fm, dm);
    return x > 0.0 ? Fm * x * std::sqrt(x) : 0.0;
  }
  double energy(double d, double dm) const
  {
    if (dm <= dy) return hertz_energy(d);
    const double Fm = loading(dm);
    const double c = span(Fm, dm);
    const double x = 1.0 - (dm - d) / c;
    return x > 0.0 ? 0.4 * Fm * c * x * x * std::sqrt(x) : 0.0;
  }
  // energy dissipated as the largest overlap rises from d0 to d1 >= d0
  double dissipated(double d0, double d1) const
  {
    if (d1 <= dy) return 0.0;
    const double lo = d0 > dy ? d0 : dy;
    double W = d0 < dy ? hertz_energy(dy) - hertz_energy(d0) : 0.0;
    W += Fy * (d1 - lo) + 0.5 * S * ((d1 - dy) * (d1 - dy) - (lo - dy) * (lo - dy));
    return W - (energy(d1, d1) - energy(d0, d0));
  }
};

// R* of two spheres (exactly R/2 for equal ones)
inline double rstar(double a, double b)
{
  return a == b ? 0.5 * a : a * b / (a + b);
}
}    // namespace

/* ---------------------------------------------------------------------- */

FixThorntonChain::FixThorntonChain(LAMMPS *lmp, int narg, char **arg) :
    Fix(lmp, narg, arg), peratom(nullptr)
{
  nchain = 0;
  wall_flag = 0;
  wall_x = 0.0;
  estar_index = yield_index = -1;
  work_local = 0.0;

  int iarg = 3;
  while (iarg < narg) {
    const char *key = arg[iarg];
    if (iarg + 1 >= narg) bad_arg(fmt::format("keyword '{}' needs a value", key));
    const char *val = arg[iarg + 1];
    if (strcmp(key, "chain") == 0) {
      if (!utils::is_integer(val)) bad_arg(fmt::format("'chain' must be an integer (got '{}')", val));
      nchain = utils::tnumeric(FLERR, val, false, lmp);
      if (nchain < 2) bad_arg(fmt::format("'chain' must be >= 2 (got '{}')", val));
    } else if (strcmp(key, "estar") == 0 || strcmp(key, "yield") == 0) {
      if (strncmp(val, "d_", 2) != 0 || val[2] == '\0')
        bad_arg(fmt::format("'{}' must name a per-atom vector d_NAME (got '{}')", key, val));
      (key[0] == 'e' ? estar_name : yield_name) = val + 2;
    } else if (strcmp(key, "wall") == 0) {
      if (!utils::is_double(val) && !utils::is_integer(val))
        bad_arg(fmt::format("'wall' must be a number (got '{}')", val));
      wall_x = utils::numeric(FLERR, val, false, lmp);
      wall_flag = 1;
    } else {
      bad_arg(fmt::format("unknown keyword '{}'", key));
    }
    iarg += 2;
  }
  if (nchain == 0) bad_arg("needs 'chain N'");
  if (estar_name.empty()) bad_arg("needs 'estar d_NAME'");
  if (yield_name.empty()) bad_arg("needs 'yield d_NAME'");

  scalar_flag = 1;
  global_freq = 1;
  extscalar = 1;
  peratom_flag = 1;
  size_peratom_cols = NPERATOM;
  peratom_freq = 1;
  restart_global = 1;
  restart_peratom = 1;
  create_attribute = 1;
  maxexchange = NPERATOM;
  comm_forward = 1;

  FixThorntonChain::grow_arrays(atom->nmax);
  atom->add_callback(Atom::GROW);
  atom->add_callback(Atom::RESTART);
  for (int i = 0; i < atom->nmax; i++)
    for (int k = 0; k < NPERATOM; k++) peratom[i][k] = 0.0;
}

/* ---------------------------------------------------------------------- */

FixThorntonChain::~FixThorntonChain()
{
  if (copymode) return;
  atom->delete_callback(id, Atom::GROW);
  atom->delete_callback(id, Atom::RESTART);
  memory->destroy(peratom);
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::bad_arg(const std::string &msg)
{
  error->all(FLERR, "Fix thornton/chain: " + msg);
}

/* ---------------------------------------------------------------------- */

int FixThorntonChain::setmask()
{
  return POST_FORCE;
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::init()
{
  if (utils::strmatch(update->integrate_style, "^respa"))
    error->all(FLERR, "Fix thornton/chain: run_style respa is not supported");
  if (!atom->radius_flag) error->all(FLERR, "Fix thornton/chain: needs atom_style sphere");
  if (atom->map_style == Atom::MAP_NONE)
    error->all(FLERR, "Fix thornton/chain: needs an atom map (atom_modify map array)");
  estar_index = custom_index(estar_name, "estar");
  yield_index = custom_index(yield_name, "yield");
}

/* ----------------------------------------------------------------------
   the per-atom vector d_NAME, with ghost values (the left neighbour's)
------------------------------------------------------------------------- */

int FixThorntonChain::custom_index(const std::string &name, const char *key)
{
  int flag = -1, cols = -1, ghost = 0;
  const int index = atom->find_custom_ghost(name.c_str(), flag, cols, ghost);
  if (index < 0 || flag != 1 || cols != 0 || !ghost)
    error->all(FLERR,
               "Fix thornton/chain: '{}' names d_{}, which is not a per-atom floating-point "
               "vector with ghosts: define it with fix property/atom d_{} ghost yes",
               key, name, name);
  return index;
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::setup(int /*vflag*/)
{
  apply(0);
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::post_force(int /*vflag*/)
{
  apply(1);
}

/* ----------------------------------------------------------------------
   add the correction F_Thornton - F_Hertz of every contact to its atoms.
   Each atom applies its own share: the owner of the contact's left atom
   computes it (and, with increment, raises its stored largest overlap and
   books the work), the owner of its right atom computes the same number
   from the left atom's stored overlap (a ghost's is communicated first),
   so no force is added to a ghost.
------------------------------------------------------------------------- */

void FixThorntonChain::apply(int increment)
{
  comm->forward_comm(this);

  double **x = atom->x;
  double **f = atom->f;
  double *radius = atom->radius;
  tagint *tag = atom->tag;
  int *mask = atom->mask;
  const int nlocal = atom->nlocal;
  const double *es = atom->dvector[estar_index];
  const double *py = atom->dvector[yield_index];

  for (int i = 0; i < nlocal; i++) {
    peratom[i][ENERGY] = 0.0;
    peratom[i][WALLF] = 0.0;
  }

  for (int i = 0; i < nlocal; i++) {
    if (!(mask[i] & groupbit)) continue;
    const tagint pos = (tag[i] - 1) % nchain;    // 0-based place in its chain

    // the contacts with the left (side -1) and right (side +1) neighbour
    for (int side = -1; side <= 1; side += 2) {
      if ((side < 0 && pos == 0) || (side > 0 && pos == nchain - 1)) continue;
      int j = atom->map(tag[i] + side);
      if (j < 0) continue;    // not even a ghost here: farther than the cutoff, open
      j = domain->closest_image(i, j);
      const int a = side > 0 ? i : j;    // the contact's left atom: its history
      const int b = side > 0 ? j : i;
      const double dx = x[a][0] - x[b][0];
      const double dyy = x[a][1] - x[b][1];
      const double dz = x[a][2] - x[b][2];
      const double r = std::sqrt(dx * dx + dyy * dyy + dz * dz);
      const double d = (radius[a] + radius[b]) - r;
      const double stored = peratom[a][DMAX];
      const double dm = d > stored ? d : stored;
      const Law law(es[a], py[a], rstar(radius[a], radius[b]));
      const bool plastic = dm > law.dy && d > 0.0;
      if (plastic) {
        const double Fa = law.force(d, dm) - law.hertz(d);
        // (x_i - x_other) / r: away from the other atom
        const double s = (side > 0 ? Fa : -Fa) / r;
        f[i][0] += s * dx;
        f[i][1] += s * dyy;
        f[i][2] += s * dz;
      }
      if (side > 0) {
        if (plastic) peratom[i][ENERGY] = law.energy(d, dm) - law.hertz_energy(d);
        if (increment && d > stored) {
          const double q = law.dissipated(stored, d);
          peratom[i][WORK] -= q;
          work_local -= q;
          peratom[i][DMAX] = d;
        }
      }
    }

    // the end wall: the last atom's right contact
    if (wall_flag && pos == nchain - 1) {
      const double d = radius[i] - (wall_x - x[i][0]);
      const double stored = peratom[i][DMAX];
      const double dm = d > stored ? d : stored;
      const Law law(es[i], py[i], radius[i]);
      if (dm > law.dy && d > 0.0) {
        const double Fa = law.force(d, dm) - law.hertz(d);
        f[i][0] -= Fa;
        peratom[i][WALLF] = -Fa;
        peratom[i][ENERGY] = law.energy(d, dm) - law.hertz_energy(d);
      }
      if (increment && d > stored) {
        const double q = law.dissipated(stored, d);
        peratom[i][WORK] -= q;
        work_local -= q;
        peratom[i][DMAX] = d;
      }
    }
  }
}

/* ---------------------------------------------------------------------- */

double FixThorntonChain::compute_scalar()
{
  double all = 0.0;
  MPI_Allreduce(&work_local, &all, 1, MPI_DOUBLE, MPI_SUM, world);
  return all;
}

/* ---------------------------------------------------------------------- */

double FixThorntonChain::memory_usage()
{
  return (double) atom->nmax * NPERATOM * sizeof(double);
}

/* ---------------------------------------------------------------------- */

int FixThorntonChain::pack_forward_comm(int n, int *list, double *buf, int /*pbc_flag*/,
                                        int * /*pbc*/)
{
  for (int k = 0; k < n; k++) buf[k] = peratom[list[k]][DMAX];
  return n;
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::unpack_forward_comm(int n, int first, double *buf)
{
  for (int k = 0; k < n; k++) peratom[first + k][DMAX] = buf[k];
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::grow_arrays(int nmax)
{
  memory->grow(peratom, nmax, NPERATOM, "thornton/chain:peratom");
  array_atom = peratom;
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::copy_arrays(int i, int j, int /*delflag*/)
{
  for (int k = 0; k < NPERATOM; k++) peratom[j][k] = peratom[i][k];
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::set_arrays(int i)
{
  for (int k = 0; k < NPERATOM; k++) peratom[i][k] = 0.0;
}

/* ---------------------------------------------------------------------- */

int FixThorntonChain::pack_exchange(int i, double *buf)
{
  for (int k = 0; k < NPERATOM; k++) buf[k] = peratom[i][k];
  return NPERATOM;
}

/* ---------------------------------------------------------------------- */

int FixThorntonChain::unpack_exchange(int nlocal, double *buf)
{
  for (int k = 0; k < NPERATOM; k++) peratom[nlocal][k] = buf[k];
  return NPERATOM;
}

/* ----------------------------------------------------------------------
   per-atom restart: [count, the NPERATOM columns]
------------------------------------------------------------------------- */

int FixThorntonChain::pack_restart(int i, double *buf)
{
  buf[0] = NPERATOM + 1;
  for (int k = 0; k < NPERATOM; k++) buf[k + 1] = peratom[i][k];
  return NPERATOM + 1;
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::unpack_restart(int nlocal, int nth)
{
  double **extra = atom->extra;
  int m = 0;
  for (int i = 0; i < nth; i++) m += static_cast<int>(extra[nlocal][m]);
  m++;
  for (int k = 0; k < NPERATOM; k++) peratom[nlocal][k] = extra[nlocal][m + k];
}

/* ---------------------------------------------------------------------- */

int FixThorntonChain::size_restart(int /*nlocal*/)
{
  return NPERATOM + 1;
}

/* ---------------------------------------------------------------------- */

int FixThorntonChain::maxsize_restart()
{
  return NPERATOM + 1;
}

/* ----------------------------------------------------------------------
   global restart: the cumulative work (summed over ranks, kept on rank 0)
------------------------------------------------------------------------- */

void FixThorntonChain::write_restart(FILE *fp)
{
  double all = 0.0;
  MPI_Allreduce(&work_local, &all, 1, MPI_DOUBLE, MPI_SUM, world);
  if (comm->me == 0) {
    int size = sizeof(double);
    fwrite(&size, sizeof(int), 1, fp);
    fwrite(&all, sizeof(double), 1, fp);
  }
}

/* ---------------------------------------------------------------------- */

void FixThorntonChain::restart(char *buf)
{
  work_local = comm->me == 0 ? reinterpret_cast<double *>(buf)[0] : 0.0;
}
