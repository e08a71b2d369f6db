// The spectroscopic tables shipped with the library, embedded at build time
// from cpp/engine/spectra/data/*.csv (internal; use isotopologue.h).
#pragma once

namespace qogi {
namespace spectra_data {
// "molecule_id,formula" rows (HITRAN molecule codes).
extern const char* const kMoleculesCsv;
// "molecule_id,local_id,global_id,formula,abundance,molar_mass_g_mol" rows.
extern const char* const kIsotopologuesCsv;
// "molecule_id,local_id,temperature_K,q" rows (TIPS-2025).
extern const char* const kTipsCsv;
}  // namespace spectra_data
}  // namespace qogi
