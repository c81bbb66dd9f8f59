/* ----------------------------------------------------------------------
   granchain: plugin registration for fix groove/drag and fix thornton/chain

   Load in an input script with
     plugin load /path/to/groove_drag.so
   The shared object is built by granchain.lammps.plugin.build_plugin(),
   which defines GRANCHAIN_LAMMPS_VERSION to the version string of the
   LAMMPS it compiles against (LAMMPS only warns on a mismatch).
------------------------------------------------------------------------- */

#include "lammpsplugin.h"

#include "fix_groove_drag.h"
#include "fix_thornton_chain.h"

using namespace LAMMPS_NS;

#ifndef GRANCHAIN_LAMMPS_VERSION
#define GRANCHAIN_LAMMPS_VERSION "22 Jul 2025"
#endif

static Fix *groove_drag_creator(LAMMPS *lmp, int argc, char **argv)
{
  return new FixGrooveDrag(lmp, argc, argv);
}

static Fix *thornton_chain_creator(LAMMPS *lmp, int argc, char **argv)
{
  return new FixThorntonChain(lmp, argc, argv);
}

extern "C" void lammpsplugin_init(void *lmp, void *handle, void *regfunc)
{
  lammpsplugin_t plugin;
  auto register_plugin = (lammpsplugin_regfunc) regfunc;

  plugin.version = GRANCHAIN_LAMMPS_VERSION;
  plugin.style = "fix";
  plugin.name = "groove/drag";
  plugin.info = "granchain groove Coulomb friction + air drag for 1D sphere chains v1.1";
  plugin.author = "granchain";
  plugin.creator.v2 = (lammpsplugin_factory2 *) &groove_drag_creator;
  plugin.handle = handle;
  (*register_plugin)(&plugin, lmp);

  plugin.name = "thornton/chain";
  plugin.info = "granchain Thornton elastic-plastic normal contact for 1D sphere chains v1.0";
  plugin.creator.v2 = (lammpsplugin_factory2 *) &thornton_chain_creator;
  (*register_plugin)(&plugin, lmp);
}
