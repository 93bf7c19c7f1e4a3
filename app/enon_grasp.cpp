// enon_grasp: search-approach-grasp on the enon, simulated or real (--help).
#include "grasp/enon_grasp.h"

int main(int argc, char** argv) { return refgrasp::grasp_app::runEnonGrasp(argc, argv); }
