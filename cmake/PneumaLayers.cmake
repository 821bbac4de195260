# The one-way dependencies of ../shared/design/ARCHITECTURE.md, checked when the project is
# configured: a target that links (publicly or privately, directly or through others) what its
# layer may not use stops the configuration with one line naming the path.

# `out`: every target `target` links, transitively, with the chain that reaches each one.
function(_pneuma_link_closure target out_targets out_chains)
  set(seen "")
  set(chains "")
  set(stack "${target}")
  set(stack_chains "${target}")
  while(stack)
    list(POP_BACK stack t)
    list(POP_BACK stack_chains chain)
    if(NOT TARGET ${t})
      continue()
    endif()
    get_target_property(aliased ${t} ALIASED_TARGET)
    if(aliased)
      set(t ${aliased})
    endif()
    if(t IN_LIST seen)
      continue()
    endif()
    list(APPEND seen ${t})
    list(APPEND chains "${chain}")
    get_target_property(type ${t} TYPE)
    set(libs "")
    if(NOT type STREQUAL "INTERFACE_LIBRARY")
      get_target_property(direct ${t} LINK_LIBRARIES)
      if(direct)
        list(APPEND libs ${direct})
      endif()
    endif()
    get_target_property(interface ${t} INTERFACE_LINK_LIBRARIES)
    if(interface)
      list(APPEND libs ${interface})
    endif()
    foreach(lib ${libs})
      string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" lib "${lib}")
      if(TARGET ${lib})
        list(APPEND stack ${lib})
        list(APPEND stack_chains "${chain} -> ${lib}")
      endif()
    endforeach()
  endwhile()
  set(${out_targets} "${seen}" PARENT_SCOPE)
  set(${out_chains} "${chains}" PARENT_SCOPE)
endfunction()

# pneuma_forbid(TARGET ... USES ...): none of the targets may link any of the others.
function(pneuma_forbid)
  cmake_parse_arguments(ARG "" "" "TARGETS;USES;WHY" ${ARGN})
  foreach(target ${ARG_TARGETS})
    _pneuma_link_closure(${target} closure chains)
    foreach(forbidden ${ARG_USES})
      if(TARGET ${forbidden})
        get_target_property(aliased ${forbidden} ALIASED_TARGET)
        if(aliased)
          set(forbidden ${aliased})
        endif()
      endif()
      list(FIND closure ${forbidden} at)
      if(NOT at EQUAL -1)
        list(GET chains ${at} chain)
        message(FATAL_ERROR "layering: ${target} must not use ${forbidden} (${ARG_WHY}), but links it: ${chain}")
      endif()
    endforeach()
  endforeach()
endfunction()

function(pneuma_check_layers)
  set(mesh_targets pneuma_mesh_geometry pneuma_mesh_io pneuma_mesh_labels pneuma_mesh_repair pneuma_mesh_anatomy
      pneuma_mesh_volume pneuma_mesh_source)
  set(below_render pneuma_core pneuma_physiology pneuma_image ${mesh_targets} pneuma_field pneuma_paper
                   pneuma_voxels pneuma_scenario pneuma_model pneuma_outputs)
  pneuma_forbid(TARGETS ${below_render} USES pneuma_render
                WHY "nothing below render links OpenGL or the renderer")
  pneuma_forbid(TARGETS pneuma_field pneuma_paper pneuma_image ${mesh_targets} pneuma_physiology pneuma_voxels
                USES pneuma_scenario yaml-cpp
                WHY "the field, the paper, image, mesh, voxels and physiology know no YAML")
  pneuma_forbid(TARGETS pneuma_physiology USES pneuma_image ${mesh_targets} WHY "physiology knows nothing of meshes")
  pneuma_forbid(TARGETS pneuma_image USES ${mesh_targets} pneuma_physiology WHY "image IO is below mesh")
  pneuma_forbid(TARGETS ${mesh_targets} USES pneuma_physiology pneuma_field pneuma_scenario pneuma_model
                WHY "mesh is below the engine")
  pneuma_forbid(TARGETS pneuma_voxels USES pneuma_scenario pneuma_model pneuma_outputs
                WHY "voxels knows tetrahedra and grids, not the run (its plugin is in outputs)")
  pneuma_forbid(TARGETS pneuma_scenario USES pneuma_model pneuma_outputs pneuma_runner
                WHY "the scenario is read before anything is computed")
  pneuma_forbid(TARGETS pneuma_model pneuma_outputs USES pneuma_runner
                WHY "the runner is the top of the engine")
  pneuma_forbid(TARGETS ${below_render} pneuma_render pneuma_runner USES pneuma_cohort
                WHY "a cohort is made of runs: only the CLI uses it")
  pneuma_forbid(TARGETS pneuma_mesh_geometry USES pneuma_mesh_io pneuma_mesh_labels pneuma_mesh_repair
                pneuma_mesh_anatomy pneuma_mesh_volume pneuma_mesh_source WHY "geometry is the bottom of mesh/")
  pneuma_forbid(TARGETS pneuma_mesh_io pneuma_mesh_labels pneuma_mesh_repair pneuma_mesh_anatomy pneuma_mesh_volume
                USES pneuma_mesh_source WHY "the surface source is the top of mesh/")
endfunction()
