/* -*- c++ -*- ----------------------------------------------------------
   granchain: fix groove/drag (LAMMPS plugin)

   Per-particle external forces on spheres lying in a V-groove, for 1D
   chains along x that roll about y:
     - groove Coulomb friction (Cundall-Strack elastic-plastic spring,
       per-atom history xi), force along x and torque about y
     - empirical air drag along x

   See fix_groove_drag.md for the full description.
------------------------------------------------------------------------- */

#ifndef LMP_FIX_GROOVE_DRAG_H
#define LMP_FIX_GROOVE_DRAG_H

#include "fix.h"

#include <string>

namespace LAMMPS_NS {

class FixGrooveDrag : public Fix {
 public:
  FixGrooveDrag(class LAMMPS *, int, char **);
  ~FixGrooveDrag() override;

  int setmask() override;
  void init() override;
  void setup(int) override;
  void post_force(int) override;

  double compute_scalar() override;
  double compute_vector(int) override;
  double memory_usage() override;

  // per-atom history xi and works: must follow atoms through migration and restarts
  void grow_arrays(int) override;
  void copy_arrays(int, int, int) override;
  void set_arrays(int) override;
  int pack_exchange(int, double *) override;
  int unpack_exchange(int, double *) override;
  int pack_restart(int, double *) override;
  void unpack_restart(int, int) override;
  int size_restart(int) override;
  int maxsize_restart() override;

  // global state (cumulative work) in restart files
  void write_restart(FILE *) override;
  void restart(char *) override;

 private:
  enum { DRAG_AS_PRINTED = 0, DRAG_ODD = 1 };
  enum { NPERATOM = 3 };    // columns of the per-atom array

  int groove_flag;    // 1 if groove Coulomb friction is on
  int drag_flag;      // 1 if air drag is on
  int rotation;       // 1 if slip includes s*R*omega_y and torque is applied
  int drag_form;      // DRAG_AS_PRINTED or DRAG_ODD

  double sfac;        // groove factor s (contact lever arm = s*R)
  double mu;          // groove friction coefficient mu_pg
  double gravity;     // g
  double kt;          // stiffness of the groove tangential spring (force/distance)
  double gamma;       // optional dashpot in parallel with the spring (force/velocity)
  double load;        // normal load of the walls beyond the weight's m*g/s (force; 0 unless given)
  // per-atom kt / gamma / load: names of fix property/atom vectors d_NAME ("" if a
  // number) and their indices in atom->dvector (-1 if a number), resolved in init()
  std::string kt_name, gamma_name, load_name;
  int kt_index, gamma_index, load_index;
  double t0;          // drag time constant T0
  double lenL;        // drag length L

  // per-atom array, 3 columns: [0] spring elongation xi (distance units),
  // [1] cumulative work done ON the atom by the groove friction, [2] the same for the
  // air drag (energy units); all three follow their atom (migration, restart)
  double **peratom;

  // cumulative work done ON the particles (this proc's atoms),
  // [0] groove friction, [1] air drag
  double work_local[2];
  double work_all[2];

  void apply(int increment);
  int custom_index(const std::string &name, const char *key);
  void check_peratom();
  [[noreturn]] void bad_arg(const std::string &msg);
  double parse_positive(const char *key, const char *val, bool allow_zero);
};

}    // namespace LAMMPS_NS

#endif
