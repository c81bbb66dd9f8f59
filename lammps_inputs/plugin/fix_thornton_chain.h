/* -*- c++ -*- ----------------------------------------------------------
   granchain: fix thornton/chain (LAMMPS plugin)

   Thornton's (1997) elastic-perfectly plastic normal contact at the
   neighbour contacts of 1D chains of spheres (atom ids in chain order) and
   at an end wall, as a correction added to the Hertz force of pair
   granular (hertz/material) and fix wall/gran. Each contact's largest
   overlap is per-atom history (contact i,i+1 on atom i, the wall's on the
   chain's last atom). See fix_thornton_chain.md.
------------------------------------------------------------------------- */

#ifndef LMP_FIX_THORNTON_CHAIN_H
#define LMP_FIX_THORNTON_CHAIN_H

#include "fix.h"

#include <string>

namespace LAMMPS_NS {

class FixThorntonChain : public Fix {
 public:
  FixThorntonChain(class LAMMPS *, int, char **);
  ~FixThorntonChain() override;

  int setmask() override;
  void init() override;
  void setup(int) override;
  void post_force(int) override;

  double compute_scalar() override;
  double memory_usage() override;

  // per-atom history and outputs: follow atoms through migration and restarts
  void grow_arrays(int) override;
  void copy_arrays(int, int, int) override;
  void set_arrays(int) override;
  int pack_exchange(int, double *) override;
  int unpack_exchange(int, double *) override;
  int pack_restart(int, double *) override;
  void unpack_restart(int, int) override;
  int size_restart(int) override;
  int maxsize_restart() override;
  // the largest overlaps of the ghosts' contacts (a neighbour owned by another rank)
  int pack_forward_comm(int, int *, double *, int, int *) override;
  void unpack_forward_comm(int, int, double *) override;

  void write_restart(FILE *) override;
  void restart(char *) override;

 private:
  // per-atom array columns (f_ID[1..4])
  enum { DMAX = 0, WORK = 1, ENERGY = 2, WALLF = 3, NPERATOM = 4 };

  tagint nchain;        // spheres per chain: atom ids b*nchain+1 ... b*nchain+nchain
  int wall_flag;        // 1: an end wall at the plane x = wall_x after each chain's last atom
  double wall_x;
  std::string estar_name, yield_name;    // per-atom d_NAME vectors of E* and p_y
  int estar_index, yield_index;

  double **peratom;
  double work_local;    // cumulative plastic work done on this rank's atoms' contacts

  void apply(int increment);
  int custom_index(const std::string &name, const char *key);
  [[noreturn]] void bad_arg(const std::string &msg);
};

}    // namespace LAMMPS_NS

#endif
