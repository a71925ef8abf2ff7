# ROS 1 bags without a ROS install: Debian 12's rosbag_storage, tf2 and message headers
# (scripts/setup.sh installs them). Their pkg-config files need ROS 2's pluginlib .pc, which Debian
# does not ship, so the headers and libraries are found here one by one. Defines the imported
# target bgkmap::rosbag_deps, linked privately by the library that holds io/rosbag_reader.cpp and
# by the tests that write bags.
set(_bgkmap_rosbag_hint "(Debian 12: librosbag-storage-dev libsensor-msgs-dev libtf2-dev libtf2-msgs-dev libbz2-dev; scripts/setup.sh)")
set(_bgkmap_rosbag_includes)
# rosbag/bag.h includes ROS 2's pluginlib, whose headers (and their own includes) lie one folder
# deeper than /usr/include: the second loop finds those folders.
foreach(_header rosbag/bag.h roslz4/lz4s.h bzlib.h sensor_msgs/PointCloud2.h sensor_msgs/LaserScan.h tf2_msgs/TFMessage.h tf2/buffer_core.h)
  string(MAKE_C_IDENTIFIER "BGKMAP_ROS_INCLUDE_${_header}" _var)
  find_path(${_var} ${_header})
  if(NOT ${_var})
    message(FATAL_ERROR "bgkmap: ${_header} not found ${_bgkmap_rosbag_hint}")
  endif()
  list(APPEND _bgkmap_rosbag_includes ${${_var}})
endforeach()
foreach(_header pluginlib/class_loader.hpp class_loader/class_loader.hpp rcutils/types.h rcpputils/env.hpp
        ament_index_cpp/get_resource.hpp)
  get_filename_component(_pkg ${_header} DIRECTORY)
  string(MAKE_C_IDENTIFIER "BGKMAP_ROS_INCLUDE_${_header}" _var)
  find_path(${_var} ${_header} PATH_SUFFIXES ${_pkg})
  if(NOT ${_var})
    message(FATAL_ERROR "bgkmap: ${_header} not found ${_bgkmap_rosbag_hint}")
  endif()
  list(APPEND _bgkmap_rosbag_includes ${${_var}})
endforeach()
set(_bgkmap_rosbag_libraries)
# bz2 and roslz4: the bag check (io/rosbag_check.cpp) decompresses chunks itself.
foreach(_lib rosbag_storage tf2 roscpp_serialization rostime cpp_common console_bridge roslz4 bz2)
  string(TOUPPER "BGKMAP_ROS_LIBRARY_${_lib}" _var)
  find_library(${_var} ${_lib})
  if(NOT ${_var})
    message(FATAL_ERROR "bgkmap: lib${_lib} not found ${_bgkmap_rosbag_hint}")
  endif()
  list(APPEND _bgkmap_rosbag_libraries ${${_var}})
endforeach()
list(REMOVE_DUPLICATES _bgkmap_rosbag_includes)
add_library(bgkmap_rosbag_deps INTERFACE IMPORTED)
target_include_directories(bgkmap_rosbag_deps SYSTEM INTERFACE ${_bgkmap_rosbag_includes})
target_link_libraries(bgkmap_rosbag_deps INTERFACE ${_bgkmap_rosbag_libraries})
add_library(bgkmap::rosbag_deps ALIAS bgkmap_rosbag_deps)
