/*
 * LD_PRELOAD shim for VTK < 9.3.1 (Debian 12's ParaView 5.11 / VTK 9.2) on an expat with
 * "reparse deferral" (expat >= 2.6.0, and Debian 12's 2.5.0-1+deb12u* security updates, which
 * backport it for CVE-2023-52425).
 *
 * VTK's XML reader feeds the header of a .vtu/.vtp to expat and stops at the start of the
 * appended data; with reparse deferral expat has not yet reported the elements before that
 * point and then trips over the binary bytes: "not well-formed (invalid token)" or "junk after
 * document element", and no appended or raw file can be read. VTK 9.3.1 fixed this by turning
 * deferral off on each parser; this shim does the same for every parser a process creates:
 *
 *   LD_PRELOAD=build/lib/libfluidcast_expat_fix.so pvbatch script.py
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <expat.h>

typedef XML_Parser (*create_fn)(const XML_Char*);
typedef XML_Parser (*create_ns_fn)(const XML_Char*, XML_Char);
typedef XML_Parser (*create_mm_fn)(
  const XML_Char*, const XML_Memory_Handling_Suite*, const XML_Char*);
typedef XML_Bool (*deferral_fn)(XML_Parser, XML_Bool);

/* The real expat function: the next definition after this library, or, when expat was only
 * loaded privately by a dlopen()ed library (Mesa's DRI drivers read their config with it),
 * expat itself. */
static void* real_symbol(const char* name)
{
  void* f = dlsym(RTLD_NEXT, name);
  if (!f)
  {
    void* lib = dlopen("libexpat.so.1", RTLD_NOW | RTLD_LOCAL);
    f = lib ? dlsym(lib, name) : NULL;
  }
  return f;
}

static XML_Parser no_deferral(XML_Parser p)
{
  deferral_fn set = (deferral_fn)real_symbol("XML_SetReparseDeferralEnabled");
  if (p && set)
  {
    set(p, XML_FALSE);
  }
  return p;
}

XML_Parser XML_ParserCreate(const XML_Char* encoding)
{
  create_fn real = (create_fn)real_symbol("XML_ParserCreate");
  return real ? no_deferral(real(encoding)) : NULL;
}

XML_Parser XML_ParserCreateNS(const XML_Char* encoding, XML_Char sep)
{
  create_ns_fn real = (create_ns_fn)real_symbol("XML_ParserCreateNS");
  return real ? no_deferral(real(encoding, sep)) : NULL;
}

XML_Parser XML_ParserCreate_MM(
  const XML_Char* encoding, const XML_Memory_Handling_Suite* mm, const XML_Char* sep)
{
  create_mm_fn real = (create_mm_fn)real_symbol("XML_ParserCreate_MM");
  return real ? no_deferral(real(encoding, mm, sep)) : NULL;
}
